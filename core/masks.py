"""Measures of boolean object masks shared by the stages and the benchmarks."""

from __future__ import annotations

import numpy as np


def mask_extent(mask: np.ndarray) -> int:
    """The object's size in pixels: the longer side of its bounding box (the image's long side when empty).

    Reaches, margins and crops scale with it, so an object framed tight or small reads the same.
    """
    rows, cols = np.nonzero(mask)
    return int(max(np.ptp(rows), np.ptp(cols)) + 1) if len(rows) else max(np.shape(mask))
