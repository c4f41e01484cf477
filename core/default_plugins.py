"""The core's own hook implementations: the defaults every family gets.

Registered first, so any installed plugin's implementation of a first-result hook is
asked before these (pluggy calls the last registered first); the defaults marked
``trylast`` are the fallbacks at the end of each chain.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from frontal3d import hookimpl, learned, learned_dense, occluders
from frontal3d.back_rules import BUILTIN_BACK_RULES
from frontal3d.family import Family
from frontal3d.stages import classify, mesh, regions, segment


@hookimpl(tryfirst=True)
def frontal3d_segment(image: np.ndarray, family: Family, settings: dict[str, Any], hints: dict[str, Any]) -> np.ndarray | None:
    """The user's mask first, then the image's alpha channel."""
    if hints.get("mask") is not None:
        return hints["mask"]
    return segment.mask_from_alpha(image)


@hookimpl(specname="frontal3d_segment")
def learned_segmenter(image: np.ndarray, family: Family, settings: dict[str, Any], hints: dict[str, Any]) -> np.ndarray | None:
    """The learned segmenter when the family's ``weights`` name one (refined on the photo's edges), else pass."""
    model = learned_dense.configured_segmenter(settings, family, image[..., :3])
    return None if model is None else model.object_mask(image[..., :3])


@hookimpl(trylast=True, specname="frontal3d_segment")
def classical_segmenter(image: np.ndarray, family: Family, settings: dict[str, Any], hints: dict[str, Any]) -> np.ndarray | None:
    """The training-free fallback: GrabCut from a border-colour model."""
    return segment.grabcut_segment(image[..., :3])


@hookimpl
def frontal3d_classifiers(family: Family) -> list[classify.Classifier]:
    """The frontal gate and subtype classifier: learned ones where the family's ``weights`` name a checkpoint."""
    return [learned.WeightsOrDefault(classify.FrontalGate()), learned.WeightsOrDefault(classify.SubtypeClassifier())]


@hookimpl(trylast=True)
def frontal3d_segment_regions(image: np.ndarray, object_mask: np.ndarray, transferred_regions: np.ndarray, family: Family, subtype: str, settings: dict[str, Any]) -> np.ndarray | None:
    """The aligned template's regions (or the learned region model's, when configured), refined by colour and a graph cut."""
    return regions.segment_regions(image, object_mask, transferred_regions, family, subtype, settings)


@hookimpl
def frontal3d_back_texture_rules() -> dict[str, Callable[..., np.ndarray]]:
    return dict(BUILTIN_BACK_RULES)


@hookimpl
def frontal3d_symmetry_rules() -> dict[str, Callable[..., tuple[np.ndarray, np.ndarray]]]:
    return {
        "none": lambda front_z, back_z, mask, region_map, params: (front_z, back_z),
        "mirror_z": lambda front_z, back_z, mask, region_map, params: mesh.apply_symmetry(front_z, back_z, mask, "mirror_z"),
    }


@hookimpl
def frontal3d_occluders(image: np.ndarray, object_mask: np.ndarray, settings: dict[str, Any]) -> np.ndarray | None:
    """People's arms and hands in front of the object (needs mediapipe; without it, none)."""
    return occluders.detect_arms_and_hands(image, object_mask)
