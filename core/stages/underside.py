"""Underside evidence for the frontal gate (issue #6): does the car show its floor?

A car seen in profile shows its side only: between the wheels the outline's bottom is
the sill, seen edge-on. Rolled about its length axis by an angle ``a`` (turned about
image-right, bottom towards the camera), its floor comes into view below the near sill,
a band ``width x sin a`` tall (about 0.07 of the car's length at 10°, 0.2 at 30°, for
width / length ~0.4). The outline cannot tell it from a taller car, but the image can: a
floor faces the ground, away from the light, so it is darker than the side above it, and
the near sill ends it in a straight step.

Read in the aligned template's frame (its similarity undoes scale and in-plane tilt, so
"up" is the template's up), on the columns between the template's wheels (central
:data:`GAP_SHARE` of the gap, where only the sill and the floor can be): from each
column's lowest object pixel upwards, the step (a rise by :data:`LIGHTNESS_STEP` within
:data:`EDGE_SPAN` samples) that best splits the lightness into a darker stretch below and
a lighter one (:data:`LOOK_DEPTH` tall) above; its height when the split reaches
:data:`LIGHTNESS_STEP`, else 0. Two look-alikes are left out: a side below lighter
windows (the lighter stretch may not reach into the template's windows) and a side below
a lit shoulder (the band must be darker than the paint, the object's
:data:`PAINT_PERCENTILE` lightness). The evidence is the median over the columns, as a
share of the outline's length (so a tall or a low car reads the same): a dark rocker
trim or the sill's rounded underside is a thin band, a floor a deep one.
Families switch the test on with ``underside_margin``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from frontal3d.render import TemplateRenders
from frontal3d.stages.align import Similarity, warp_mask

#: The template region whose gap (between the front and the rear wheels) is searched.
WHEEL_REGION = "wheels"
#: The template region the lighter stretch above a step may not reach into: a side darker than its windows is no floor.
WINDOW_REGION = "windows"
#: Share of the gap between the wheels searched, centred (the arches' edges are left out).
GAP_SHARE = 0.6
#: Deepest band searched, as a share of the outline's length (a 45° roll shows about 0.28).
BAND_REACH = 0.3
#: Height of the stretch above a step whose lightness the band is compared with, share of the length.
LOOK_DEPTH = 0.03
#: Lab lightness (0-100) by which the stretch above the step must be lighter than the band.
LIGHTNESS_STEP = 8.0
#: Samples either side of a step over which the lightness must rise by LIGHTNESS_STEP (a sill is an
#: edge; a side lit from above darkens towards the bottom smoothly).
EDGE_SPAN = 2
#: Percentile of the object's lightness taken as the paint's shade (above the median: a floor rolled
#: 30° into view covers a large share of the object).
PAINT_PERCENTILE = 60
#: Fewest searched columns that make evidence.
MIN_COLUMNS = 5


@dataclass(frozen=True)
class UndersideEvidence:
    """Median height of the dark band along the outline's bottom between the wheels, as a share of its length."""

    band: float


def underside_evidence(image: np.ndarray, object_mask: np.ndarray, render: TemplateRenders,
                       similarity: Similarity) -> UndersideEvidence:
    """The floor band between the wheels, seen in the aligned template's frame (0: no evidence)."""
    if WHEEL_REGION not in render.region_names:
        return UndersideEvidence(0.0)
    wheel_columns = np.flatnonzero((render.front_regions == render.region_names.index(WHEEL_REGION)).any(axis=0))
    if wheel_columns.size < 2:
        return UndersideEvidence(0.0)
    gap = int(np.argmax(np.diff(wheel_columns)))
    rear, front = wheel_columns[gap], wheel_columns[gap + 1]
    inverse, shape = similarity.inverse(), render.mask.shape
    mask = warp_mask(object_mask, inverse, shape)
    lightness = cv2.cvtColor(np.ascontiguousarray(image[..., :3], dtype=np.uint8), cv2.COLOR_RGB2LAB)[..., 0]
    lightness = cv2.warpAffine(lightness.astype(np.float32) * np.float32(100.0 / 255.0), inverse.matrix,
                               (shape[1], shape[0]), flags=cv2.INTER_LINEAR)
    ceiling = None
    if WINDOW_REGION in render.region_names:
        windows = render.front_regions == render.region_names.index(WINDOW_REGION)
        ceiling = np.where(windows.any(axis=0), shape[0] - 1 - np.argmax(windows[::-1], axis=0), -1)
    return floor_band(lightness, mask, rear + 0.5 * (1 - GAP_SHARE) * (front - rear),
                      front - 0.5 * (1 - GAP_SHARE) * (front - rear), ceiling)


def floor_band(lightness: np.ndarray, mask: np.ndarray, x0: float, x1: float,
               ceiling: np.ndarray | None = None) -> UndersideEvidence:
    """The dark band along the bottom of an upright outline (image-down = ground) over columns ``x0``-``x1``,
    read below ``ceiling`` (per column, the lowest row not read; -1: up to the outline's top)."""
    object_columns = np.flatnonzero(mask.any(axis=0))
    if object_columns.size < 2:
        return UndersideEvidence(0.0)
    length = float(np.ptp(object_columns) + 1)
    reach, look = max(3, int(BAND_REACH * length)), max(2, int(round(LOOK_DEPTH * length)))
    columns = np.arange(int(np.ceil(x0)), int(np.floor(x1)) + 1)
    columns = columns[(columns >= 0) & (columns < mask.shape[1])]
    columns = columns[mask[:, columns].sum(axis=0) >= 2 * look + 4]
    if columns.size < MIN_COLUMNS:
        return UndersideEvidence(0.0)
    bottom = mask.shape[0] - 1 - np.argmax(mask[::-1, columns], axis=0)
    top = np.argmax(mask[:, columns], axis=0)
    if ceiling is not None:
        top = np.maximum(top, ceiling[columns] + 1)
    # Profiles upwards from each column's lowest pixel (sample 0, half background), cut off at the column's top.
    rows = bottom[:, None] - np.arange(reach + look + EDGE_SPAN + 1)[None, :]
    inside = rows >= top[:, None]
    profiles = np.where(inside, lightness[np.clip(rows, 0, None), columns[:, None]], 0.0)
    sums = np.concatenate([np.zeros((len(columns), 1)), np.cumsum(profiles, axis=1)], axis=1)
    depths = np.arange(EDGE_SPAN + 1, reach + 1)
    below = (sums[:, depths] - sums[:, 1:2]) / (depths - 1)  # samples 1 .. d-1
    above = (sums[:, depths + look] - sums[:, depths]) / look  # samples d .. d+look-1
    edge = (sums[:, depths + EDGE_SPAN] - sums[:, depths]) / EDGE_SPAN - (sums[:, depths] - sums[:, depths - EDGE_SPAN]) / EDGE_SPAN
    crisp = inside[:, depths + look - 1] & (edge >= LIGHTNESS_STEP)
    # A side below a lit shoulder is the paint itself, not darker than it.
    crisp &= below <= np.percentile(lightness[mask], PAINT_PERCENTILE) - LIGHTNESS_STEP
    contrast = np.where(crisp, above - below, -np.inf)
    best = np.argmax(contrast, axis=1)
    bands = np.where(contrast[np.arange(len(columns)), best] >= LIGHTNESS_STEP, depths[best], 0)
    return UndersideEvidence(float(np.median(bands)) / length)
