"""Occlusions: things in front of the object, and the silhouette and regions behind them.

Paper section 3.2.3. Occluder masks come from the ``frontal3d_occluders`` hook (every
plugin's masks are OR-ed) and from the user's ``--occluder-mask``. The occluded part of
the silhouette is rebuilt from the aligned template; the region map is then completed
over it so the texture stage can inpaint each region from itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from frontal3d.stages.regions import reconstruct_region_map


@dataclass
class RebuiltSilhouette:
    """The object's mask with occluded parts restored, and which pixels were occluded."""

    mask: np.ndarray
    occluded: np.ndarray
    original_area: int

    def summary(self) -> dict[str, Any]:
        area = int(self.mask.sum())
        return {
            "occluded_fraction": round(float(self.occluded.sum()) / max(area, 1), 4),
            "restored_pixels": int(area - self.original_area),
        }


def find_occluders(plugins: Any, image: np.ndarray, object_mask: np.ndarray, settings: dict[str, Any], user_mask: np.ndarray | None) -> np.ndarray | None:
    """OR of every occluder plugin's mask and the user's; None when nothing occludes."""
    found = [np.asarray(m, dtype=bool) for m in plugins.hook.frontal3d_occluders(image=image, object_mask=object_mask, settings=settings) if m is not None]
    if user_mask is not None:
        found.append(user_mask)
    if not found:
        return None
    combined = np.logical_or.reduce(found)
    return combined if combined.any() else None


def rebuild_silhouette(object_mask: np.ndarray, occluders: np.ndarray, aligned_template_mask: np.ndarray) -> RebuiltSilhouette:
    """Restore the silhouette where occluders cover it, using the aligned template.

    Where an occluder overlaps the aligned template, the object continues behind it:
    those pixels join the mask, which is then closed so bites along the boundary fill.
    """
    if not occluders.any():
        return RebuiltSilhouette(object_mask, np.zeros_like(object_mask), int(object_mask.sum()))
    size = max(3, int(round(0.02 * max(object_mask.shape))) | 1)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    near_object = cv2.dilate(object_mask.astype(np.uint8), kernel) > 0
    behind = occluders & aligned_template_mask & (near_object | object_mask)
    restored = object_mask | behind
    restored = cv2.morphologyEx(restored.astype(np.uint8), cv2.MORPH_CLOSE, kernel) > 0
    restored &= object_mask | aligned_template_mask
    occluded = restored & occluders
    return RebuiltSilhouette(restored, occluded, int(object_mask.sum()))


def rebuild_regions(regions: np.ndarray, object_mask: np.ndarray, occluded: np.ndarray, n_regions: int) -> np.ndarray:
    """Give every pixel of the (rebuilt) mask a region, filling occluded ones from neighbours."""
    needs_fill = object_mask & ((regions < 0) | occluded)
    return reconstruct_region_map(np.where(object_mask, regions, -1), object_mask, needs_fill)
