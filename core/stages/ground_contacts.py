"""Ground-contact evidence for the frontal gate (issue #6): does the object stand on paired feet?

A car seen in profile touches the ground at two places, its front and rear wheels: the
far-side wheels hide behind the near ones. Turned about image-up by an angle ``a``, the
far wheels come out beside the near ones, ``track * sin a`` away: the outline's lowest
rows then show four contact patches in two pairs (about 0.18 of the car's length apart at
30°, 0.06 at 10°). The silhouette tests cannot see this, since a car turned 30° still fits
its template's outline, and it is read off the outline alone, so paint and light cannot
fool it.

Measured in the aligned template's frame (the alignment's similarity undoes scale and
in-plane tilt, so "down" is the template's ground): the outline's bottom row per column,
the columns within :data:`CONTACT_DEPTH` of the lowest one, and their runs. The two runs at
each end of the outline are that end's pair, and each pair's spread (run centre to run centre)
over the outline's length is its split. Not the biggest gap between runs: past about 40° the
far wheels come out further than half the (foreshortened) wheelbase, so the gap between a near
and a far wheel outgrows the gap between the axles (at 45°, about 0.25 against 0.17 of the
length). The evidence is the smaller of the two splits: both ends must show a pair, since one
odd run (a skirt, a tow hook, a spoiler dipping low) is not a turn. Near 60° one axle's far
wheel stands where the other's near wheel does and the two merge: three runs, evenly spaced
(gaps within :data:`EVEN_GAPS` of each other), share their middle one between the two pairs;
three runs with a pair at one end only (a tow hook, a twin axle) are no turn. Families switch
the test on with ``contact_pair_margin``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from frontal3d.render import TemplateRenders
from frontal3d.stages.align import Similarity, warp_mask

#: How far above the lowest bottom row (share of the outline's height) a column still touches the ground.
CONTACT_DEPTH = 0.03
#: Runs of contact columns closer than this (share of the outline's length) are one patch.
MERGE_GAP = 0.01
#: Three runs count as two pairs sharing the middle run when the smaller gap is at least this share of the larger.
EVEN_GAPS = 0.5


@dataclass(frozen=True)
class ContactEvidence:
    """How the outline's ground contacts split: runs found and the smaller axle split (share of the length)."""

    runs: int
    split: float


def contact_evidence(object_mask: np.ndarray, render: TemplateRenders, similarity: Similarity) -> ContactEvidence:
    """The object's ground contacts, seen in the aligned template's frame."""
    return contact_split(warp_mask(object_mask, similarity.inverse(), render.mask.shape))


def contact_split(mask: np.ndarray) -> ContactEvidence:
    """Ground contacts of an upright outline (image-down = ground); no split with fewer than three runs,
    nor with three unevenly spaced ones."""
    columns = np.flatnonzero(mask.any(axis=0))
    rows = np.flatnonzero(mask.any(axis=1))
    if columns.size < 2 or rows.size < 2:
        return ContactEvidence(0, 0.0)
    length, height = float(np.ptp(columns)), float(np.ptp(rows))
    # The lowest object row per column: argmax of the flipped column finds it without a loop.
    bottom = (mask.shape[0] - 1 - np.argmax(mask[::-1, columns], axis=0)).astype(np.float64)
    above_ground = _ground_line(columns.astype(np.float64), bottom) - bottom
    touching = columns[above_ground <= max(1.0, CONTACT_DEPTH * height)]
    breaks = np.flatnonzero(np.diff(touching) > max(2.0, MERGE_GAP * length))
    centres = np.array([run.mean() for run in np.split(touching, breaks + 1)])
    gaps = np.diff(centres)
    if centres.size < 3 or (centres.size == 3 and gaps.min() < EVEN_GAPS * gaps.max()):
        return ContactEvidence(int(centres.size), 0.0)
    split = min(centres[1] - centres[0], centres[-1] - centres[-2]) / length
    return ContactEvidence(int(centres.size), float(split))


def _ground_line(x: np.ndarray, bottom: np.ndarray) -> np.ndarray:
    """The line the outline stands on, at each ``x``: the longest hull edge that no bottom point lies
    below. A photo or a placement tilted by a degree lifts one end of a car by more than
    :data:`CONTACT_DEPTH`, so the ground is this line, not the lowest row."""
    corners = cv2.convexHull(np.stack([x, bottom], axis=1).astype(np.float32))[:, 0].astype(np.float64)
    best, best_width = None, 0.0
    for (x0, y0), (x1, y1) in zip(corners, np.roll(corners, -1, axis=0)):
        if abs(x1 - x0) <= best_width:
            continue
        line = y0 + (y1 - y0) / (x1 - x0) * (x - x0)
        if np.all(bottom <= line + 0.5):  # image rows grow downwards: nothing stands below the ground
            best, best_width = line, abs(x1 - x0)
    return np.full_like(bottom, bottom.max()) if best is None else best
