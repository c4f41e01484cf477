"""Learned dense models: the object segmenter and the inner-region segmenter (paper 3.1.1, 3.1.4).

Both are one small encoder-decoder (:class:`frontal3d.train.TinyUNet`) trained by
``frontal3d train segmenter|regions`` on ``frontal3d synth`` data, stored in the same
checkpoint layout as the classifiers (:mod:`frontal3d.learned`: task, family, classes,
input size, a reference input whose output is replayed at load).

- ``segmenter``: the whole photo, letterboxed to a square -> p(object) per pixel. The
  network sees the photo at low resolution: it knows where the object is, not where its
  edge runs, so its answer corrects the seeds of the classical GrabCut
  (:func:`frontal3d.stages.segment.grabcut_segment`), which puts the edge on the image's
  own colour edges.
- ``regions``: the object crop (object on black plus its mask) -> one probability per
  region of the family's *region set*: every subtype's region names, in first-seen order.
  One network serves all subtypes (they share most regions: body, wheels...), and at
  prediction only the chosen subtype's regions compete.

Torch is imported only when a checkpoint is loaded.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from frontal3d import occluders as people_detector
from frontal3d.errors import ConfigError
from frontal3d.family import Family
from frontal3d.learned import (
    DENSE_ARCHITECTURE, DENSE_TASKS, LoadedModel, cached_model, check_family, check_reference, crop_square, cut_square, object_crop, one_line,
    read_checkpoint, to_tensor,
)
from frontal3d.stages.segment import grabcut_segment

if TYPE_CHECKING:
    import torch

#: Side of the square the dense networks see.
DENSE_INPUT_SIZE = 96
#: Channel widths of the encoder's four levels (about 0.23 M parameters).
DENSE_WIDTHS = (16, 32, 48, 64)
#: Classes of the object segmenter, in output order.
SEGMENTER_CLASSES = ("background", "object")
#: p(object) above this somewhere: the network sees an object.
OBJECT_SEEN = 0.5
#: When the network is sure (p > OBJECT_SEEN) of less object in the photo than this share of
#: what it is sure of in the photo's negative, it is blind to the object's tones (a white
#: plane or a pale car its synthetic training rarely showed), and the negative's p joins in.
NEGATIVE_VIEW_SHARE = 0.5


def family_region_names(family: Family) -> list[str]:
    """Every subtype's region names, in first-seen order: the classes of a family's region model."""
    names: list[str] = []
    for subtype in family.subtypes:
        names += [name for name in family.regions[subtype] if name not in names]
    return names


def letterbox(image: np.ndarray, size: int) -> tuple[np.ndarray, tuple[int, int, int]]:
    """The RGB image (or a mask) padded to a square (edges repeated) and resized to size x size; (top, left, side) of the image in the square."""
    image = image[..., :3] if image.ndim == 3 else image
    height, width = image.shape[:2]
    side = max(height, width)
    top, left = (side - height) // 2, (side - width) // 2
    square = cv2.copyMakeBorder(np.ascontiguousarray(image), top, side - height - top, left, side - width - left, cv2.BORDER_REPLICATE)
    return cv2.resize(square, (size, size), interpolation=cv2.INTER_AREA), (top, left, side)


def regions_input(image: np.ndarray, mask: np.ndarray, size: int) -> np.ndarray:
    """The region model's input: the object crop on black plus its mask as a fourth channel (size x size x 4 uint8)."""
    mask = np.asarray(mask, dtype=bool)
    crop_mask = cv2.resize(cut_square(mask.astype(np.uint8) * 255, *crop_square(mask)), (size, size), interpolation=cv2.INTER_AREA)
    return np.dstack([object_crop(image, mask, size), crop_mask])


def dense_probabilities(model: "torch.nn.Module", inputs: np.ndarray) -> np.ndarray:
    """N x S x S x C uint8 inputs -> N x S x S x K class probabilities (float64)."""
    import torch

    model.eval()
    with torch.no_grad():
        return torch.softmax(model(to_tensor(inputs)), dim=1).permute(0, 2, 3, 1).numpy().astype(np.float64)


class DenseModel(LoadedModel):
    """A loaded segmenter or region checkpoint."""

    def object_probability(self, image: np.ndarray) -> np.ndarray:
        """p(object) per pixel of the image (float32), upsampled from the network's grid."""
        square, (top, left, side) = letterbox(image, self.input_size)
        probability = dense_probabilities(self.model, square[None])[0, ..., self.classes.index("object")].astype(np.float32)
        height, width = image.shape[:2]
        return cv2.resize(probability, (side, side), interpolation=cv2.INTER_LINEAR)[top : top + height, left : left + width]

    def object_mask(self, image: np.ndarray) -> np.ndarray | None:
        """The object's mask at the image's resolution, or None when the network sees no object."""
        probability = self.object_probability_either_tone(image)
        if not (probability > OBJECT_SEEN).any():
            return None
        return grabcut_segment(image[..., :3], object_probability=probability)

    def object_probability_either_tone(self, image: np.ndarray) -> np.ndarray:
        """p(object), taking the photo's negative's view too (the larger p) where the network
        sees far more object in the negative (:data:`NEGATIVE_VIEW_SHARE`)."""
        probability = self.object_probability(image)
        negative = self.object_probability(255 - np.asarray(image[..., :3], dtype=np.uint8))
        if np.count_nonzero(probability > OBJECT_SEEN) < NEGATIVE_VIEW_SHARE * np.count_nonzero(negative > OBJECT_SEEN):
            return np.maximum(probability, negative)
        return probability

    def region_map(self, image: np.ndarray, mask: np.ndarray, region_names: tuple[str, ...] | list[str]) -> np.ndarray:
        """Labels indexing ``region_names`` (a subtype's regions) on the image grid, -1 outside ``mask``."""
        mask = np.asarray(mask, dtype=bool)
        if not mask.any():
            return np.full(mask.shape, -1, np.int32)
        probabilities = dense_probabilities(self.model, regions_input(image, mask, self.input_size)[None])[0]
        subtype_probabilities = probabilities[..., [self.classes.index(name) for name in region_names]].astype(np.float32)
        top, left, side = crop_square(mask)
        full = cv2.resize(subtype_probabilities, (side, side), interpolation=cv2.INTER_LINEAR).reshape(side, side, -1)
        on_grid = np.zeros(mask.shape + (len(region_names),), np.float32)
        # the crop square may reach outside the image: paste its part that lies inside
        y0, x0 = max(0, top), max(0, left)
        y1, x1 = min(mask.shape[0], top + side), min(mask.shape[1], left + side)
        on_grid[y0:y1, x0:x1] = full[y0 - top : y1 - top, x0 - left : x1 - left]
        return np.where(mask, on_grid.argmax(axis=-1), -1).astype(np.int32)


def load_dense(path: Path | str, task: str, family: Family | None = None) -> DenseModel:
    """Load a ``segmenter`` or ``regions`` checkpoint, checking it fits ``task`` and ``family``.

    Raises :class:`ConfigError` with a one-line message for a missing, corrupt or mismatched checkpoint.
    """
    from frontal3d.train import TinyUNet

    if task not in DENSE_TASKS:
        raise ConfigError(f"unknown dense task {task!r} (tasks: {', '.join(DENSE_TASKS)})")
    path = Path(path)
    checkpoint = read_checkpoint(path, task)
    if family is not None:
        expected = list(SEGMENTER_CLASSES) if task == "segmenter" else family_region_names(family)
        check_family(path, checkpoint, family, expected, "segmenter classes" if task == "segmenter" else "regions")
    classes = [str(c) for c in checkpoint["classes"]]
    reference = checkpoint["reference_input"]
    try:
        model = TinyUNet(int(reference.shape[-1]), len(classes), tuple(int(w) for w in checkpoint["widths"]))
        model.load_state_dict(checkpoint["state_dict"])
    except (RuntimeError, KeyError, TypeError, AttributeError, IndexError) as exc:
        raise ConfigError(f"{path}: weights do not fit the {DENSE_ARCHITECTURE} network ({one_line(exc)})") from exc
    model.eval()
    dense = DenseModel(path, task, checkpoint["family"], classes, int(checkpoint["input_size"]), model, dict(checkpoint.get("training", {})))
    check_reference(path, lambda: dense_probabilities(model, reference.numpy()[None])[0], checkpoint["reference_probabilities"])
    return dense


def configured_model(settings: dict[str, Any], task: str, family: Family) -> DenseModel | None:
    """The family's ``weights`` checkpoint for ``task``, loaded once per process, or None when none is configured."""
    path = (settings.get("weights") or {}).get(task)
    return cached_model(path, task, family, load_dense) if path else None


def segmenter_weights(settings: dict[str, Any], image: np.ndarray) -> str | None:
    """The segmenter checkpoint for ``image``: ``weights.segmenter_with_people`` when the family
    names one and the people detector sees a person (a pose or a face), else ``weights.segmenter``.

    A network trained longer learns clutter better but also learns the drawn people of its
    synthetic data too well, and then doubts a real guitarist's wood beside a face
    (families/guitar/weights/README.md). The detector runs on every photo anyway (faces are
    cut from the mask, arms are occluders), so choosing per photo costs nothing."""
    weights = settings.get("weights") or {}
    if weights.get("segmenter_with_people") and people_detector.person_seen(image):
        return weights["segmenter_with_people"]
    return weights.get("segmenter")


def configured_segmenter(settings: dict[str, Any], family: Family, image: np.ndarray) -> DenseModel | None:
    """The loaded :func:`segmenter_weights` checkpoint for ``image``, or None when none is configured."""
    path = segmenter_weights(settings, image)
    return cached_model(path, "segmenter", family, load_dense) if path else None
