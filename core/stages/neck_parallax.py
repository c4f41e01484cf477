"""Neck-parallax evidence for the frontal gate (issue #6): is the guitar turned about its neck?

A guitar's neck sits on the face, in front of the body's mid-plane. Seen straight on,
the neck's centre line runs into the body's midline. Turned about image-up by an angle
``a``, the body's outline stays mirror-symmetric about the body's own centre, but the
neck moves sideways by its height above the mid-plane times ``sin a``: the neck ends
up beside the body's midline (parallax). The silhouette tests cannot see this, since
the outline's size and shape barely change at 30-45°, and it is read off the
silhouette alone, so textures and lighting cannot fool it.

Both lines are measured in the aligned template's frame (the silhouette alignment's
similarity carries the object onto it, which undoes scale and in-plane tilt): the
neck's centre line from the row centres of its lower half, the body's midline from
the mid-points of the rows between its waist and its lower bout. Each is extended to
the row where the template's neck meets its body, and their sideways gap, as a share
of the body's width, is the offset. Comparing the lines where they meet, not the body's
centre with the far end of the neck, keeps a slightly bent photo (or synth's banana
bend) from reading as a turn. Rows that an occluder nobody flagged cuts (an arm across
the body) leave their line as outliers; when too many do, or the gap is wider than any
turn makes, there is no evidence. The template's own offset (zero for a symmetric one)
is subtracted. Families switch the test on with ``parallax_margin``; templates
without both regions give no evidence.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace

import numpy as np

from frontal3d.render import TemplateRenders
from frontal3d.stages.align import Similarity, warp_mask
from frontal3d.stages.turned_views import content_key

#: The part that stands in front of the mid-plane, and the part whose midline it should meet.
RAISED_REGION = "neck"
BASE_REGION = "body"
#: Neck rows used: the lower half of the neck, minus its last few rows (the heel flares).
NECK_ROWS = (0.5, 0.95)
#: How far (in neck widths) from the template's neck a row's pixels still count as neck.
NECK_WINDOW = 2.5
#: Body rows used, as shares of the body's height from its top: the waist and the lower bout
#: (the upper bout's horns and cutaways are often lopsided; the bottom's rows are too short).
BODY_ROWS = (0.4, 0.85)
#: Fewest usable rows of either part for a measurement.
MIN_ROWS = 5
#: Share of each part's rows that must agree with its fitted line: an arm across the body or a
#: hand on the neck moves the rows it cuts, and too many cut rows leave no evidence.
MIN_INLIER_SHARE = 0.6
#: Largest gap (share of the body's width) a turn can make: a guitar's neck stands at most about a
#: sixth of the body's width in front of its mid-plane. A larger gap is a damaged mask, not a turn.
MAX_TURN_OFFSET = 0.25
#: Shares of the band around the template's neck (2 x NECK_WINDOW neck widths) outside which a row of
#: the outline is no neck: under the first nothing lies there, over the second it is 1.5 necks wide.
NO_NECK_FILL = 0.05
WIDE_NECK_FILL = 0.3
_TEMPLATE_CACHE: dict[str, "_Layout | None"] = {}
_CACHE_LIMIT = 32


@dataclass(frozen=True)
class ParallaxEvidence:
    """Sideways gap between the neck's centre line and the body's midline, as a share of the body's width."""

    object_offset: float
    template_offset: float

    @property
    def offset(self) -> float:
        """How far the object's neck sits off its body's midline beyond the template's (signed)."""
        return self.object_offset - self.template_offset


@dataclass(frozen=True)
class _Layout:
    """Which template rows and columns hold the neck and the body, and where they meet."""

    neck_rows: np.ndarray
    neck_columns: tuple[float, float]
    body_rows: np.ndarray
    junction_row: int
    offset: float


def parallax_evidence(object_mask: np.ndarray, render: TemplateRenders, similarity: Similarity) -> ParallaxEvidence:
    """The object's neck offset vs the template's; zero offsets (no evidence) when the template lacks a neck
    or body, or the object's rows do not show one (hidden, cut by an occluder, far off any turn)."""
    layout = _layout(render)
    if layout is None:
        return ParallaxEvidence(0.0, 0.0)
    offset = _offset(warp_mask(object_mask, similarity.inverse(), render.mask.shape), layout)
    if offset is None:
        return ParallaxEvidence(0.0, 0.0)
    return ParallaxEvidence(offset, layout.offset)


def _layout(render: TemplateRenders) -> _Layout | None:
    """The template's neck and body rows (cached by template content); None without both regions."""
    # Region maps are part of the key: the same shape with other regions has another layout.
    key = content_key(render) + hashlib.sha1(np.ascontiguousarray(render.front_regions[::4, ::4]).tobytes()).hexdigest()
    if key not in _TEMPLATE_CACHE:
        if len(_TEMPLATE_CACHE) >= _CACHE_LIMIT:
            _TEMPLATE_CACHE.pop(next(iter(_TEMPLATE_CACHE)))
        _TEMPLATE_CACHE[key] = _template_layout(render)
    return _TEMPLATE_CACHE[key]


def _template_layout(render: TemplateRenders) -> _Layout | None:
    """The rows to measure (the template's neck above its body), and the template's own gap."""
    if RAISED_REGION not in render.region_names or BASE_REGION not in render.region_names:
        return None
    neck = render.front_regions == render.region_names.index(RAISED_REGION)
    body = render.front_regions == render.region_names.index(BASE_REGION)
    body_rows = np.flatnonzero(body.any(axis=1))
    if body_rows.size < MIN_ROWS:
        return None
    top, bottom = int(body_rows.min()), int(body_rows.max())
    # Only the neck's rows above the body: its lower half then ends where it meets the body.
    neck_rows = np.flatnonzero(neck.any(axis=1))
    neck_rows = neck_rows[neck_rows < top]
    if neck_rows.size < 2 * MIN_ROWS:
        return None
    used_neck = neck_rows[int(NECK_ROWS[0] * neck_rows.size) : int(NECK_ROWS[1] * neck_rows.size)]
    neck_columns = np.flatnonzero(neck.any(axis=0))
    centre, width = neck_columns.mean(), np.ptp(neck_columns) + 1
    used_body = np.arange(int(top + BODY_ROWS[0] * (bottom - top)), int(top + BODY_ROWS[1] * (bottom - top)))
    layout = _Layout(used_neck, (centre - NECK_WINDOW * width, centre + NECK_WINDOW * width), used_body, top, 0.0)
    offset = _offset(render.mask, layout)
    return None if offset is None else replace(layout, offset=offset)


def _offset(mask: np.ndarray, layout: _Layout) -> float | None:
    """Neck centre line minus body midline at the junction row, over the body's width; None if too few
    rows agree with the lines or the gap is larger than any turn makes."""
    columns = np.arange(mask.shape[1])
    near_neck = (columns >= layout.neck_columns[0]) & (columns <= layout.neck_columns[1])
    neck_points = [(row, columns[mask[row] & near_neck].mean()) for row in layout.neck_rows if (mask[row] & near_neck).sum() >= 2]
    body_points = []
    for row in layout.body_rows:
        filled = np.flatnonzero(mask[row])
        if filled.size >= 2:
            body_points.append((row, 0.5 * (filled.min() + filled.max()), filled.max() - filled.min()))
    if len(neck_points) < MIN_ROWS or len(body_points) < MIN_ROWS:
        return None
    neck, body = np.array(neck_points), np.array(body_points)
    neck_fit, body_fit = _robust_line(neck[:, 0], neck[:, 1]), _robust_line(body[:, 0], body[:, 1])
    if neck_fit is None or body_fit is None:
        return None
    (neck_line, _), (body_line, body_inliers) = neck_fit, body_fit
    gap = np.polyval(neck_line, layout.junction_row) - np.polyval(body_line, layout.junction_row)
    offset = float(gap / max(body[body_inliers, 2].max(), 1.0))
    return offset if abs(offset) <= MAX_TURN_OFFSET else None


def _robust_line(rows: np.ndarray, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Line through the row centres without the rows more than 3 robust deviations (at least a
    pixel) off it, starting from their median (the template frame keeps both lines near upright,
    and a median ignores a minority of cut rows); None when fewer than MIN_INLIER_SHARE stay."""
    line = np.array([0.0, float(np.median(centres))])
    for _ in range(3):
        residual = np.abs(centres - np.polyval(line, rows))
        inliers = residual <= 3.0 * max(1.0, 1.4826 * float(np.median(residual)))
        if inliers.sum() < max(MIN_ROWS, MIN_INLIER_SHARE * rows.size):
            return None
        line = np.polyfit(rows[inliers], centres[inliers], 1)
    return line, inliers


def neckless_share(object_mask: np.ndarray, render: TemplateRenders, similarity: Similarity) -> float | None:
    """Share of the template's lower-neck rows (the rows the parallax uses) where the outline shows
    no neck: within NECK_WINDOW neck widths of the neck's centre it fills under NO_NECK_FILL of the
    band, or more than WIDE_NECK_FILL. None when the template has no neck above a body.

    A guitar's neck fills 0.12-0.25 of each row's band (shared renders, synthetic samples, photos;
    its share is 0). An outline that only a guitar's body fits has the template's neck laid over a
    wider part (a limousine's bonnet) or off the object, in most rows (0.38-1.0 on the shared car
    and airplane photos, scaled, turned and re-saved).
    """
    layout = _layout(render)
    if layout is None:
        return None
    low, high = (int(np.clip(round(edge), 0, render.mask.shape[1])) for edge in layout.neck_columns)
    if high <= low:
        return None
    mask = warp_mask(object_mask, similarity.inverse(), render.mask.shape)
    fill = mask[layout.neck_rows, low:high].sum(axis=1) / (high - low)
    return float(np.mean((fill < NO_NECK_FILL) | (fill > WIDE_NECK_FILL)))
