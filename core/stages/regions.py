"""Inner-region segmentation (paper 3.1.4) and region-map reconstruction (3.2.3).

Training-free default: the aligned template's region map is a strong prior (the bridge
of a guitar is where the template's bridge landed, give or take the shape difference);
colour models per region, learned from the prior's eroded cores, then move region
boundaries onto the image's colour changes with a graph cut (alpha-expansion, Potts
smoothness), and a distance term keeps each region near where the template put it.
With a learned region model configured (``weights = {regions = "..."}``), its prediction
replaces the template's as the prior and the same refinement runs on it.
"""

from __future__ import annotations

from typing import Any

import cv2
import maxflow
import numpy as np
from scipy.ndimage import gaussian_filter

from frontal3d import learned_dense
from frontal3d.errors import InputError
from frontal3d.family import Family

#: Cost that forbids a label (alpha-expansion needs finite costs).
_FORBIDDEN = 1e6
#: How far a region boundary may move from the prior: this fraction of the object's
#: long side, at least MIN_SHIFT pixels (the template is aligned, not yet warped).
MAX_SHIFT_FRACTION = 0.05
MIN_SHIFT = 12
#: Unary cost per pixel of distance from a label's transferred region.
DISTANCE_COST = 0.15
#: Lab histogram bins per channel of the region colour models; smoothing in bins.
COLOUR_BINS = 16
COLOUR_SMOOTHING = 1.0
#: Share of a uniform colour distribution mixed into each model, so no colour is impossible.
UNIFORM_SHARE = 0.02


#: A region's piece at least this fraction of its largest piece is a real part (the
#: other wing), not a speck to clean away.
MAIN_PIECE_FRACTION = 0.25


def reconstruct_region_map(region_map: np.ndarray, object_mask: np.ndarray, fill_mask: np.ndarray) -> np.ndarray:
    """Give every object pixel one region: each region's main pieces kept, gaps filled.

    Keeps each region's main components (the largest, and any at least
    :data:`MAIN_PIECE_FRACTION` of it: an airplane's two wings are one region in two
    pieces); pixels of smaller components, pixels
    in ``fill_mask`` (occluded) and unlabelled object pixels are filled by
    alpha-expansion with distance-to-region unaries (the paper's "distance-based graph
    cuts regularization"). Outside the object the map is -1.
    """
    object_mask = np.asarray(object_mask, dtype=bool)
    fill_mask = np.asarray(fill_mask, dtype=bool)
    _check_shapes(region_map, object_mask, fill_mask)
    kept = np.full(region_map.shape, -1, np.int32)
    labels = [int(label) for label in np.unique(region_map[object_mask & ~fill_mask]) if label >= 0]
    if not labels:
        return np.where(object_mask, 0, -1).astype(np.int32)
    for label in labels:
        kept[_main_pieces((region_map == label) & object_mask & ~fill_mask)] = label
    todo = object_mask & (kept < 0)
    if not todo.any():
        return kept
    distances = np.stack([_distance_to(kept == label) for label in labels], axis=-1)
    unary = np.where(todo[..., None], distances, np.where(kept[..., None] == np.array(labels), 0.0, _FORBIDDEN))
    solved = _alpha_expansion(unary, object_mask, smoothness=2.0)
    result = np.where(object_mask, np.array(labels)[np.maximum(solved, 0)], -1)
    # A filled gap can touch a region only through its small parts; keep the main pieces.
    return _main_pieces_only(result.astype(np.int32), object_mask, labels)


def segment_regions(image_rgb: np.ndarray, object_mask: np.ndarray, transferred_regions: np.ndarray, family: Family,
                    subtype: str, settings: dict[str, Any]) -> np.ndarray:
    """The object's region map: the learned model's prediction when configured, else the transferred template's, refined."""
    region_names = family.regions[subtype]
    model = learned_dense.configured_model(settings, "regions", family)
    prior = transferred_regions if model is None else model.region_map(image_rgb, object_mask, region_names)
    return refine_regions(image_rgb, object_mask, prior, len(region_names))


def refine_regions(
    image_rgb: np.ndarray,
    object_mask: np.ndarray,
    transferred_regions: np.ndarray,
    n_regions: int,
    smoothness: float = 3.0,
    colour_weight: float = 1.0,
) -> np.ndarray:
    """Move the transferred template regions onto the image's colour boundaries.

    Each region's colour model (a smoothed Lab histogram) comes from the eroded core
    of its transferred area; the unary is the colour's negative log-likelihood times
    ``colour_weight`` plus a cost growing with the distance to the transferred region
    (a region may move at most about 5 % of the object's size); ``smoothness`` is the
    Potts cost per pair of differently labelled neighbours. Regions the prior does not
    show stay absent. Returns int32 labels in [0, n_regions), -1 outside the object.
    """
    object_mask = np.asarray(object_mask, dtype=bool)
    transferred_regions = np.asarray(transferred_regions)
    _check_shapes(transferred_regions, object_mask, image_rgb[..., 0])
    if not object_mask.any():
        raise InputError("cannot segment regions: the object mask is empty")
    labels = [label for label in range(n_regions) if ((transferred_regions == label) & object_mask).any()]
    if len(labels) < 2:
        return reconstruct_region_map(transferred_regions, object_mask, np.zeros_like(object_mask))
    bins = _colour_bins(image_rgb)
    colour_costs, distances = [], []
    for label in labels:
        region = (transferred_regions == label) & object_mask
        core = cv2.erode(region.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        colour_costs.append(_colour_cost(bins, bins[core if core.sum() >= 20 else region]))
        distances.append(_distance_to(region))
    # Distances count from the nearest transferred region, so object pixels the template
    # did not cover (it is only aligned, not yet warped) still take their nearest region.
    distance = np.stack(distances, axis=-1)
    distance -= distance.min(axis=-1, keepdims=True)
    ys, xs = np.nonzero(object_mask)
    max_shift = max(MIN_SHIFT, MAX_SHIFT_FRACTION * max(np.ptp(ys), np.ptp(xs)))
    unary = colour_weight * np.stack(colour_costs, axis=-1) + np.where(distance > max_shift, _FORBIDDEN, DISTANCE_COST * distance)
    solved = _alpha_expansion(unary, object_mask, smoothness)
    refined = np.where(object_mask, np.array(labels)[np.maximum(solved, 0)], -1).astype(np.int32)
    return reconstruct_region_map(refined, object_mask, np.zeros_like(object_mask))


def _colour_bins(image_rgb: np.ndarray) -> np.ndarray:
    """Each pixel's flat Lab histogram bin index."""
    lab = cv2.cvtColor(np.ascontiguousarray(image_rgb[..., :3], dtype=np.uint8), cv2.COLOR_RGB2LAB)
    q = (lab.astype(np.int32) * COLOUR_BINS) // 256
    return (q[..., 0] * COLOUR_BINS + q[..., 1]) * COLOUR_BINS + q[..., 2]


def _colour_cost(bins: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Negative log-likelihood of each pixel's colour under the smoothed histogram of ``samples``."""
    histogram = np.bincount(samples, minlength=COLOUR_BINS**3).astype(np.float64).reshape((COLOUR_BINS,) * 3)
    histogram = gaussian_filter(histogram, COLOUR_SMOOTHING, mode="constant")
    probability = (1.0 - UNIFORM_SHARE) * histogram / histogram.sum() + UNIFORM_SHARE / COLOUR_BINS**3
    return -np.log(probability.ravel())[bins]


def _distance_to(region: np.ndarray) -> np.ndarray:
    """Euclidean distance (pixels) from every pixel to ``region`` (huge where it is empty)."""
    if not region.any():
        return np.full(region.shape, _FORBIDDEN)
    return cv2.distanceTransform((~region).astype(np.uint8), cv2.DIST_L2, 5).astype(np.float64)


def _main_pieces(region: np.ndarray) -> np.ndarray:
    """The region's largest component and every component at least MAIN_PIECE_FRACTION of it."""
    count, components, stats, _ = cv2.connectedComponentsWithStats(region.astype(np.uint8), connectivity=4)
    if count <= 1:
        return np.zeros(region.shape, bool)
    areas = stats[1:, cv2.CC_STAT_AREA]
    return np.isin(components, 1 + np.flatnonzero(areas >= MAIN_PIECE_FRACTION * areas.max()))


def _main_pieces_only(region_map: np.ndarray, object_mask: np.ndarray, labels: list[int]) -> np.ndarray:
    """Drop each label's small pieces, then give the dropped pixels their nearest kept label."""
    kept = np.full(region_map.shape, -1, np.int32)
    for label in labels:
        kept[_main_pieces(region_map == label)] = label
    orphans = object_mask & (kept < 0)
    if orphans.any():
        _, nearest = cv2.distanceTransformWithLabels((kept < 0).astype(np.uint8), cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
        seeds = kept >= 0
        label_of_seed = np.zeros(int(nearest.max()) + 1, np.int32)
        label_of_seed[nearest[seeds]] = kept[seeds]
        kept[orphans] = label_of_seed[nearest[orphans]]
    return kept


def _alpha_expansion(unary: np.ndarray, object_mask: np.ndarray, smoothness: float) -> np.ndarray:
    """Alpha-expansion (PyMaxflow) with a Potts term, on the object's bounding box only.

    Pixels outside the object get an extra label that only they can take, so the
    object's border does not pull any region outward. Returns label indices, -1 outside.
    """
    ys, xs = np.nonzero(object_mask)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    box_unary = unary[y0:y1, x0:x1]
    inside = object_mask[y0:y1, x0:x1]
    n = box_unary.shape[-1]
    full = np.empty(box_unary.shape[:2] + (n + 1,), np.float64)
    full[..., :n] = np.where(inside[..., None], box_unary, _FORBIDDEN)
    full[..., n] = np.where(inside, 10 * _FORBIDDEN, 0.0)
    potts = smoothness * (1.0 - np.eye(n + 1))
    initial = np.where(inside, np.argmin(full[..., :n], axis=-1), n).astype(np.int32)
    solved = maxflow.fastmin.aexpansion_grid(full, potts, max_cycles=3, labels=initial)
    out = np.full(object_mask.shape, -1, np.int32)
    out[y0:y1, x0:x1] = np.where(inside, solved, -1)
    return out


def _check_shapes(labels: np.ndarray, *others: np.ndarray) -> None:
    for other in others:
        if np.shape(other)[:2] != np.shape(labels)[:2]:
            raise InputError(f"region map is {np.shape(labels)[1]}x{np.shape(labels)[0]} but the object mask/image is "
                             f"{np.shape(other)[1]}x{np.shape(other)[0]}")
