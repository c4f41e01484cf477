"""Measures of boolean object masks shared by the stages and the benchmarks."""

from __future__ import annotations

import cv2
import numpy as np


def mask_extent(mask: np.ndarray) -> int:
    """The object's size in pixels: the longer side of its bounding box (the image's long side when empty).

    Reaches, margins and crops scale with it, so an object framed tight or small reads the same.
    """
    rows, cols = np.nonzero(mask)
    return int(max(np.ptp(rows), np.ptp(cols)) + 1) if len(rows) else max(np.shape(mask))


def pieces_touching(mask: np.ndarray, other: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """The 8-connected pieces of ``mask`` that touch ``other`` grown by the structuring element ``reach``."""
    _count, pieces = cv2.connectedComponents(np.asarray(mask, dtype=np.uint8), connectivity=8)
    touching = np.unique(pieces[(cv2.dilate(np.asarray(other, dtype=np.uint8), reach) > 0) & (pieces > 0)])
    return np.isin(pieces, touching)


#: Radius (pixels) up to which OpenCV's disc morphology costs less than a distance transform
#: (both about 0.1 s on a 16-megapixel mask at this radius; the disc's cost grows with its area).
DISC_MORPHOLOGY_MAX_RADIUS = 16


def within(mask: np.ndarray, radius: float) -> np.ndarray:
    """Pixels no further than ``radius`` from ``mask``: a dilation by a disc (none when the mask is empty).

    Beyond DISC_MORPHOLOGY_MAX_RADIUS by a distance transform, whose cost does not grow with the
    radius: a reach that scales with the object took seconds per call as a disc on a phone
    photo's full resolution. The two differ by OpenCV's rounding of the disc's rows, along the rim.
    """
    mask = np.asarray(mask, dtype=bool)
    if radius <= DISC_MORPHOLOGY_MAX_RADIUS:
        return cv2.dilate(mask.astype(np.uint8), disc(max(0, round(radius)))) > 0
    return cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE) <= radius


def inset(mask: np.ndarray, radius: float) -> np.ndarray:
    """Pixels of ``mask`` further than ``radius`` from its outside: an erosion by a disc (see :func:`within`)."""
    return ~within(~np.asarray(mask, dtype=bool), radius)


def opened(mask: np.ndarray, radius: float) -> np.ndarray:
    """``mask`` without the parts a disc of the radius does not fit in: a morphological opening (see :func:`within`)."""
    return within(inset(mask, radius), radius)


def disc(radius: int) -> np.ndarray:
    """A filled disc of the radius, as a structuring element for OpenCV's morphology."""
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
