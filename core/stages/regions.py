"""Inner-region segmentation (paper 3.1.4) and region-map reconstruction (3.2.3).

Training-free default: the aligned template's region map is a strong prior (the bridge
of a guitar is where the template's bridge landed, give or take the shape difference);
colour models per region, learned from the prior's eroded cores, then move region
boundaries onto the image's edges with a graph cut (alpha-expansion, Potts smoothness).
"""

from __future__ import annotations

import cv2
import maxflow
import numpy as np

#: Cost that forbids a label (alpha-expansion needs finite costs).
_FORBIDDEN = 1e6
#: How far (pixels at the working resolution) a region boundary may move from the prior.
MAX_SHIFT = 12


def reconstruct_region_map(region_map: np.ndarray, object_mask: np.ndarray, fill_mask: np.ndarray) -> np.ndarray:
    """Give every object pixel one region: one connected component per region, gaps filled.

    Keeps the largest component of each region; pixels of smaller components, pixels
    in ``fill_mask`` (occluded) and unlabelled object pixels are filled by
    alpha-expansion with distance-to-region unaries (the paper's "distance-based graph
    cuts regularization"). Outside the object the map is -1.
    """
    kept = np.full(region_map.shape, -1, np.int32)
    labels = [int(l) for l in np.unique(region_map[object_mask & ~fill_mask]) if l >= 0]
    for label in labels:
        region = (region_map == label) & object_mask & ~fill_mask
        count, components, stats, _ = cv2.connectedComponentsWithStats(region.astype(np.uint8), connectivity=4)
        if count > 1:
            kept[components == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))] = label
    if not labels:
        return np.where(object_mask, 0, -1).astype(np.int32)
    todo = object_mask & (kept < 0)
    if not todo.any():
        return kept
    distances = np.stack([_distance_to(kept == label) for label in labels], axis=-1)
    unary = np.where(todo[..., None], distances, np.where(kept[..., None] == np.array(labels), 0.0, _FORBIDDEN))
    solved = _alpha_expansion(unary, object_mask, smoothness=2.0)
    result = np.where(object_mask, np.array(labels)[np.maximum(solved, 0)], -1)
    return result.astype(np.int32)


def refine_regions(image: np.ndarray, object_mask: np.ndarray, transferred: np.ndarray, n_regions: int, colour_weight: float = 1.0, smoothness: float = 3.0) -> np.ndarray:
    """Move the transferred template regions onto the image's colour boundaries.

    Each region's colour model (a Gaussian in Lab) comes from the core of its
    transferred area; the unary adds the distance to the transferred region so a
    region can move at most about ``MAX_SHIFT`` pixels. Regions the prior does not
    show stay absent.
    """
    labels = [l for l in range(n_regions) if ((transferred == l) & object_mask).any()]
    if len(labels) < 2:
        return reconstruct_region_map(transferred, object_mask, np.zeros_like(object_mask))
    lab = cv2.cvtColor(image[..., :3], cv2.COLOR_RGB2LAB).astype(np.float64)
    costs = []
    for label in labels:
        region = (transferred == label) & object_mask
        core = cv2.erode(region.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        samples = lab[core if core.sum() >= 20 else region]
        distance = _distance_to(region)
        costs.append(colour_weight * _gaussian_cost(lab, samples) + np.where(distance > MAX_SHIFT, _FORBIDDEN, 0.15 * distance))
    unary = np.stack(costs, axis=-1)
    solved = _alpha_expansion(unary, object_mask, smoothness)
    refined = np.where(object_mask, np.array(labels)[np.maximum(solved, 0)], -1).astype(np.int32)
    return reconstruct_region_map(refined, object_mask, np.zeros_like(object_mask))


def _gaussian_cost(lab: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Negative log-likelihood of each pixel's colour under a Gaussian fitted to ``samples``."""
    mean = samples.mean(axis=0)
    covariance = np.cov(samples.T) + np.eye(3) * 25.0 if len(samples) > 3 else np.eye(3) * 100.0
    inverse = np.linalg.inv(covariance)
    diff = lab - mean
    mahalanobis = np.einsum("...i,ij,...j->...", diff, inverse, diff)
    return np.minimum(0.5 * mahalanobis + 0.5 * np.log(np.linalg.det(covariance)), 60.0)


def _distance_to(region: np.ndarray) -> np.ndarray:
    """Euclidean distance (pixels) from every pixel to ``region`` (huge where it is empty)."""
    if not region.any():
        return np.full(region.shape, _FORBIDDEN)
    return cv2.distanceTransform((~region).astype(np.uint8), cv2.DIST_L2, 5).astype(np.float64)


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
    full[..., n] = np.where(inside, _FORBIDDEN, 0.0)
    potts = smoothness * (1.0 - np.eye(n + 1))
    initial = np.where(inside, np.argmin(full[..., :n], axis=-1), n).astype(np.int32)
    solved = maxflow.fastmin.aexpansion_grid(full, potts, max_cycles=3, labels=initial)
    out = np.full(object_mask.shape, -1, np.int32)
    out[y0:y1, x0:x1] = np.where(inside, solved, -1)
    return out
