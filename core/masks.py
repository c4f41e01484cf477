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


def disc(radius: int) -> np.ndarray:
    """A filled disc of the radius, as a structuring element for OpenCV's morphology."""
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
