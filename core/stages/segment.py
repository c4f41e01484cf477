"""Object segmentation (paper 3.1.1): training-free defaults of the segmenter chain.

The chain (``frontal3d_segment`` hook) asks, in order: the user's mask, the alpha
channel, learned segmenters from plugins, then :func:`grabcut_segment`, which needs no
training: a background colour model from the image border seeds OpenCV's GrabCut.
"""

from __future__ import annotations

import cv2
import numpy as np

#: Components smaller than this fraction of the largest are noise, not objects.
MIN_OBJECT_FRACTION = 0.05
#: Long side of the image GrabCut runs on; the mask is upsampled and its edge refined.
GRABCUT_SIZE = 400


def mask_from_alpha(image: np.ndarray) -> np.ndarray | None:
    """The alpha channel as the mask, or None when there is none or it is fully opaque."""
    if image.ndim != 3 or image.shape[2] != 4:
        return None
    alpha = image[..., 3]
    if alpha.min() == alpha.max():
        return None
    return alpha > 127


def split_objects(mask: np.ndarray) -> list[np.ndarray]:
    """Connected components of ``mask``, largest first, tiny specks dropped."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if count <= 1:
        return []
    areas = stats[1:, cv2.CC_STAT_AREA]
    order = np.argsort(-areas)
    keep = [i for i in order if areas[i] >= MIN_OBJECT_FRACTION * areas[order[0]] and areas[i] >= 16]
    return [labels == (i + 1) for i in keep]


def grabcut_segment(image: np.ndarray, iterations: int = 5) -> np.ndarray | None:
    """Segment the object in front of a plain or mildly cluttered background.

    Pixels near the border are background; pixels far in colour from every border
    colour cluster are probable foreground. GrabCut then settles the boundary at a
    working size, and the mask is upsampled and smoothed at full resolution. Returns
    None when nothing object-like stands out (under 1 % of the image, or a region
    touching all four borders).
    """
    height, width = image.shape[:2]
    scale = min(1.0, GRABCUT_SIZE / max(height, width))
    small = cv2.resize(image[..., :3], (max(1, round(width * scale)), max(1, round(height * scale))), interpolation=cv2.INTER_AREA)
    lab = cv2.cvtColor(small, cv2.COLOR_RGB2LAB).astype(np.float32)
    border = max(2, round(0.03 * max(small.shape[:2])))
    border_mask = np.zeros(small.shape[:2], bool)
    border_mask[:border], border_mask[-border:], border_mask[:, :border], border_mask[:, -border:] = True, True, True, True
    distance = _distance_to_border_colours(lab, border_mask)
    threshold = max(12.0, float(np.percentile(distance[border_mask], 99)) * 1.5)
    init = np.full(small.shape[:2], cv2.GC_PR_BGD, np.uint8)
    init[distance > threshold] = cv2.GC_PR_FGD
    if (init == cv2.GC_PR_FGD).mean() < 0.005:
        return None
    init[border_mask] = cv2.GC_BGD
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.grabCut(cv2.cvtColor(small, cv2.COLOR_RGB2BGR), init, None, bgd, fgd, iterations, cv2.GC_INIT_WITH_MASK)
    found = (init == cv2.GC_FGD) | (init == cv2.GC_PR_FGD)
    found = _clean(found)
    if found.mean() < 0.01:
        return None
    if found[0].any() and found[-1].any() and found[:, 0].any() and found[:, -1].any():
        return None
    soft = cv2.resize(found.astype(np.float32), (width, height), interpolation=cv2.INTER_LINEAR)
    soft = cv2.GaussianBlur(soft, (0, 0), sigmaX=max(0.5, 0.5 / scale))
    return soft > 0.5


def _distance_to_border_colours(lab: np.ndarray, border_mask: np.ndarray, clusters: int = 6) -> np.ndarray:
    """Each pixel's Lab distance to the nearest of a few border colour clusters."""
    samples = lab[border_mask].reshape(-1, 3)
    k = min(clusters, len(samples))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 20, 1.0)
    _, _, centres = cv2.kmeans(samples, k, None, criteria, 2, cv2.KMEANS_PP_CENTERS)
    flat = lab.reshape(-1, 1, 3)
    distance = np.sqrt(((flat - centres[None]) ** 2).sum(axis=2)).min(axis=1)
    return distance.reshape(lab.shape[:2])


def _clean(mask: np.ndarray) -> np.ndarray:
    """Open away specks, keep the main components, fill small holes."""
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    mask = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, kernel) > 0
    objects = split_objects(mask)
    if not objects:
        return np.zeros_like(mask)
    mask = np.logical_or.reduce(objects)
    count, labels, stats, _ = cv2.connectedComponentsWithStats((~mask).astype(np.uint8), connectivity=4)
    edge_labels = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    small = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] < 0.002 * mask.size)
    fill = np.setdiff1d(small, edge_labels)
    return mask | np.isin(labels, fill)
