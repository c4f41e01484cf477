"""Object segmentation (paper 3.1.1): training-free defaults of the segmenter chain.

The chain (``frontal3d_segment`` hook) asks, in order: the user's mask, the alpha
channel, learned segmenters from plugins, then :func:`grabcut_segment`, which needs no
training: a background colour model from the image border seeds OpenCV's GrabCut.
"""

from __future__ import annotations


import cv2
import numpy as np


#: Components smaller than this fraction of the largest are clutter, not objects.
MIN_OBJECT_FRACTION = 0.15
#: Components smaller than this many pixels are specks whatever the largest is.
MIN_OBJECT_PIXELS = 16
#: Long side of the image GrabCut first runs on (speed); the edge is refined at full size.
GRABCUT_SIZE = 400
#: Long side above which the full-resolution edge refinement runs on a downscaled copy.
REFINE_MAX_SIZE = 1600
#: Width of the image border, as a fraction of the long side, taken as background.
BORDER_FRACTION = 0.03
#: Holes smaller than this fraction of the object are filled (specular spots, logos).
MAX_FILLED_HOLE = 0.01
#: Below this fraction of the image, what GrabCut found is noise, not an object.
MIN_FOREGROUND = 0.01


def mask_from_alpha(image: np.ndarray) -> np.ndarray | None:
    """The alpha channel as the mask, or None when there is none or it is fully opaque."""
    if image.ndim != 3 or image.shape[2] != 4:
        return None
    alpha = image[..., 3]
    if alpha.min() == alpha.max():
        return None
    return alpha > 127


def split_objects(mask: np.ndarray) -> list[np.ndarray]:
    """Connected components of ``mask``, largest first, specks and small clutter dropped."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(np.asarray(mask, dtype=np.uint8), connectivity=8)
    if count <= 1:
        return []
    areas = stats[1:, cv2.CC_STAT_AREA]
    order = np.argsort(-areas, kind="stable")
    floor = max(MIN_OBJECT_PIXELS, MIN_OBJECT_FRACTION * areas[order[0]])
    return [labels == (i + 1) for i in order if areas[i] >= floor]


def grabcut_segment(image: np.ndarray, shape_prior: np.ndarray | None = None, iterations: int = 5) -> np.ndarray | None:
    """Segment the object(s) in front of a plain or mildly cluttered background.

    Pixels near the border are background; pixels far in colour from every border
    colour cluster are probable foreground (``shape_prior``, a bool mask of where the
    object probably is, adds its interior and rules out what lies far outside it).
    GrabCut settles the boundary at a working size; the mask is then upsampled and its
    edge refined by a second GrabCut in a thin band at full resolution. Returns None
    when nothing object-like stands out (under 1 % of the image, or a region touching
    all four borders, which is background the border model could not explain).
    """
    rgb = np.ascontiguousarray(image[..., :3], dtype=np.uint8)
    height, width = rgb.shape[:2]
    scale = min(1.0, GRABCUT_SIZE / max(height, width))
    small_size = (max(1, round(width * scale)), max(1, round(height * scale)))
    small = cv2.resize(rgb, small_size, interpolation=cv2.INTER_AREA)
    init = _initial_labels(small, None if shape_prior is None else _resize_mask(shape_prior, small.shape[:2]))
    if init is None:
        return None
    _grabcut(small, init, iterations)
    found = _clean(_foreground(init))
    if found.mean() < MIN_FOREGROUND or _touches_all_borders(found):
        return None
    refined = _refine_edge(rgb, found)
    refined = _clean(refined)
    if not refined.any():
        return None
    return refined


def _initial_labels(small: np.ndarray, prior: np.ndarray | None) -> np.ndarray | None:
    """GrabCut's initial label map; None when no pixel differs from the background."""
    lab = cv2.cvtColor(cv2.GaussianBlur(small, (0, 0), 1.0), cv2.COLOR_RGB2LAB).astype(np.float32)
    border = max(2, round(BORDER_FRACTION * max(small.shape[:2])))
    border_mask = np.zeros(small.shape[:2], bool)
    border_mask[:border] = border_mask[-border:] = True
    border_mask[:, :border] = border_mask[:, -border:] = True
    distance = _distance_to_border_colours(lab, border_mask)
    # Border pixels are the background's own spread (noise, gradients): beyond it is "different".
    threshold = max(12.0, 1.5 * float(np.percentile(distance[border_mask], 98)))
    different = cv2.morphologyEx((distance > threshold).astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)) > 0
    salient = np.zeros_like(different)
    for component in split_objects(different & ~border_mask):
        salient |= component
    init = np.full(small.shape[:2], cv2.GC_PR_BGD, np.uint8)
    init[salient] = cv2.GC_PR_FGD
    if prior is not None and prior.any():
        reach = max(3, round(0.1 * max(small.shape[:2])))
        near = cv2.dilate(prior.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1,) * 2)) > 0
        init[~near] = cv2.GC_BGD
        init[prior & near] = cv2.GC_PR_FGD
    init[border_mask] = cv2.GC_BGD
    if (init == cv2.GC_PR_FGD).mean() < MIN_FOREGROUND / 2:
        return None
    return init


def _refine_edge(rgb: np.ndarray, found_small: np.ndarray) -> np.ndarray:
    """Upsample the working-size mask and let GrabCut re-decide a thin band around its edge."""
    height, width = rgb.shape[:2]
    refine_scale = min(1.0, REFINE_MAX_SIZE / max(height, width))
    size = (max(1, round(width * refine_scale)), max(1, round(height * refine_scale)))
    target = rgb if refine_scale == 1.0 else cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
    soft = cv2.resize(found_small.astype(np.float32), size, interpolation=cv2.INTER_LINEAR)
    upsampled = soft > 0.5
    band = max(2, round(1.5 * max(size) / max(found_small.shape)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * band + 1,) * 2)
    inner = cv2.erode(upsampled.astype(np.uint8), kernel) > 0
    outer = cv2.dilate(upsampled.astype(np.uint8), kernel) > 0
    if inner.any() and (~outer).any():
        labels = np.where(upsampled, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)
        labels[inner] = cv2.GC_FGD
        labels[~outer] = cv2.GC_BGD
        ys, xs = np.nonzero(outer)
        pad = 4 * band
        y0, y1 = max(0, ys.min() - pad), min(size[1], ys.max() + pad + 1)
        x0, x1 = max(0, xs.min() - pad), min(size[0], xs.max() + pad + 1)
        crop = np.ascontiguousarray(labels[y0:y1, x0:x1])
        _grabcut(np.ascontiguousarray(target[y0:y1, x0:x1]), crop, 2)
        upsampled = np.zeros_like(upsampled)
        upsampled[y0:y1, x0:x1] = _foreground(crop)
    if refine_scale == 1.0:
        return upsampled
    return cv2.resize(upsampled.astype(np.float32), (width, height), interpolation=cv2.INTER_LINEAR) > 0.5


def _grabcut(rgb: np.ndarray, labels: np.ndarray, iterations: int) -> None:
    """cv2.grabCut in place on ``labels`` (mask initialisation), with fresh colour models."""
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.grabCut(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), labels, None, bgd, fgd, iterations, cv2.GC_INIT_WITH_MASK)


def _foreground(labels: np.ndarray) -> np.ndarray:
    return (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)


def _distance_to_border_colours(lab: np.ndarray, border_mask: np.ndarray, clusters: int = 6) -> np.ndarray:
    """Each pixel's Lab distance to the nearest of a few border colour clusters."""
    samples = np.ascontiguousarray(lab[border_mask].reshape(-1, 3))
    k = min(clusters, len(samples))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 20, 1.0)
    cv2.setRNGSeed(0)
    _, _, centres = cv2.kmeans(samples, k, None, criteria, 2, cv2.KMEANS_PP_CENTERS)
    flat = lab.reshape(-1, 1, 3)
    distance = np.sqrt(((flat - centres[None]) ** 2).sum(axis=2)).min(axis=1)
    return distance.reshape(lab.shape[:2])


def _resize_mask(mask: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    return cv2.resize(np.asarray(mask, dtype=np.uint8), (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST) > 0


def _touches_all_borders(mask: np.ndarray) -> bool:
    return bool(mask[0].any() and mask[-1].any() and mask[:, 0].any() and mask[:, -1].any())


def _clean(mask: np.ndarray) -> np.ndarray:
    """Open away specks, keep the object-sized components, fill holes under 1 % of them."""
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    mask = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, kernel) > 0
    objects = split_objects(mask)
    if not objects:
        return np.zeros_like(mask)
    mask = np.logical_or.reduce(objects)
    _, labels, stats, _ = cv2.connectedComponentsWithStats((~mask).astype(np.uint8), connectivity=4)
    edge_labels = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    small = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] < MAX_FILLED_HOLE * mask.sum())
    return mask | np.isin(labels, np.setdiff1d(small, edge_labels))
