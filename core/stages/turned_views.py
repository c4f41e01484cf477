"""Turned-template hypotheses for the frontal gate (issue #6): is the object seen turned?

A silhouette alone barely tells a car turned 30° from a shorter car, so the frontal
gate asks a sharper question: does a template *turned* by 30-90° (about image-up or
image-right) explain the object's outline better than the same template in its
canonical view? A turned car shows its blunt front or back face beside the side and
its outline's ends change shape; these changes survive the normalisation that hides a
plain change of scale. It pays off where the family's shapes vary less than a turn
changes them (cars); guitar bodies and plane planforms vary so much that a turned
template often fits a frontal one better, so the gate uses it only when the family's
``turned_margin`` setting asks for it.

Turned silhouettes come from the template's front and back depth renders (every
template pixel is a solid segment between its front and back surface), so no mesh is
needed at classification time; they are computed once per template and kept in memory.
Shapes are compared after a moment normalisation (centroid, area, and the in-plane
rotation the silhouette alignment found) and a small nudge search, which costs a few
tens of milliseconds per image.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import cv2
import numpy as np

from frontal3d.render import TemplateRenders
from frontal3d.stages.align import Similarity

#: Side of the square grid on which normalised silhouettes are compared.
GRID = 64
#: Square root of a normalised silhouette's area, in grid pixels (leaves room for elongated shapes).
NORMALISED_ROOT_AREA = GRID / 3.2
#: Turns (degrees, either way) that count as the canonical view, as the paper's ±10°.
FRONTAL_TURNS = (0.0, 10.0)
#: Turns (degrees, either way) that count as a wrongly turned view.
TURNED_TURNS = (30.0, 45.0, 60.0, 75.0, 90.0)
#: Long side, in pixels, of the template maps the turned silhouettes are built from.
SOURCE_SIZE = 128
#: Turned silhouettes kept in memory, by template content.
_CACHE: dict[str, "Hypotheses"] = {}
_CACHE_LIMIT = 32
#: Grid-pixel shifts and scales tried around the moment placement of the object's outline.
NUDGE_SHIFT = 1.5
NUDGE_SCALES = (0.95, 1.0, 1.05)


@dataclass(frozen=True)
class Hypotheses:
    """Normalised silhouettes of one template turned about image-up ("yaw") and image-right ("pitch")."""

    masks: np.ndarray  # (H, GRID, GRID) float32 coverage in [0, 1]
    axes: tuple[str, ...]  # "yaw" or "pitch" per hypothesis
    turns: np.ndarray  # (H,) degrees, signed


@dataclass(frozen=True)
class TurnEvidence:
    """The best canonical-view and best turned-view agreement with the object's outline."""

    frontal_iou: float
    turned_iou: float
    turned_axis: str
    turned_degrees: float

    @property
    def margin(self) -> float:
        """How much better the canonical view explains the outline than any turned view (negative: turned wins)."""
        return self.frontal_iou - self.turned_iou


def turned_hypotheses(render: TemplateRenders) -> Hypotheses:
    """The template's canonical and turned silhouettes, normalised; cached by template content."""
    key = content_key(render)
    if key not in _CACHE:
        if len(_CACHE) >= _CACHE_LIMIT:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = _build_hypotheses(render)
    return _CACHE[key]


def turn_evidence(object_mask: np.ndarray, renders: dict[str, TemplateRenders], similarities: dict[str, Similarity]) -> TurnEvidence:
    """Compare the object's outline with every subtype's template in canonical and turned views.

    ``similarities`` (template -> image, from the silhouette alignment) give the object's
    in-plane rotation, so a tilted photo is not mistaken for a turned object.
    """
    frontal_best, turned_best = -1.0, (-1.0, "yaw", 0.0)
    for subtype, render in renders.items():
        hypotheses = turned_hypotheses(render)
        outline = _normalised_mask(object_mask, similarities[subtype].angle)
        ious = _soft_iou(hypotheses.masks[:, None], _nudged(outline)[None]).max(axis=1)
        canonical = np.abs(hypotheses.turns) <= max(FRONTAL_TURNS)
        frontal_best = max(frontal_best, float(ious[canonical].max()))
        turned = np.flatnonzero(~canonical)
        best = turned[np.argmax(ious[turned])]
        if ious[best] > turned_best[0]:
            turned_best = (float(ious[best]), hypotheses.axes[best], float(hypotheses.turns[best]))
    return TurnEvidence(frontal_iou=frontal_best, turned_iou=turned_best[0], turned_axis=turned_best[1], turned_degrees=turned_best[2])


def _nudged(outline: np.ndarray) -> np.ndarray:
    """The outline shifted by up to NUDGE_SHIFT grid pixels and scaled by NUDGE_SCALES: a moment
    placement is off by a little for shapes with thin parts, which would blur the comparison."""
    centre = GRID / 2.0 - 0.5
    variants = []
    for scale in NUDGE_SCALES:
        for dy in (-NUDGE_SHIFT, 0, NUDGE_SHIFT):
            for dx in (-NUDGE_SHIFT, 0, NUDGE_SHIFT):
                matrix = np.float32([[scale, 0, centre * (1 - scale) + dx], [0, scale, centre * (1 - scale) + dy]])
                variants.append(cv2.warpAffine(outline, matrix, (GRID, GRID), flags=cv2.INTER_LINEAR, borderValue=0.0))
    return np.array(variants)


def _soft_iou(masks: np.ndarray, outline: np.ndarray) -> np.ndarray:
    """IoU of each coverage map in ``masks`` with ``outline`` (fuzzy min/max, so sub-pixel edges count)."""
    inter = np.minimum(masks, outline).sum(axis=(-2, -1))
    union = np.maximum(masks, outline).sum(axis=(-2, -1))
    return inter / np.maximum(union, 1e-9)


def content_key(render: TemplateRenders) -> str:
    """Identifies a template by its maps (renders are rebuilt per run, so identity would not do)."""
    digest = hashlib.sha1(np.packbits(render.mask).tobytes())
    digest.update(np.nan_to_num(render.front_depth[::8, ::8]).tobytes())
    digest.update(np.nan_to_num(render.back_depth[::8, ::8]).tobytes())
    return digest.hexdigest()


def _build_hypotheses(render: TemplateRenders) -> Hypotheses:
    """Turn the template and rasterise its silhouette; canonical view first."""
    factor = max(1, render.resolution // SOURCE_SIZE)
    rows, cols = np.nonzero(render.mask[::factor, ::factor])
    # Depths in (subsampled) pixel units, so a turn mixes like units.
    to_pixels = 1.0 / (render.pixel_size * factor)
    front = render.front_depth[::factor, ::factor][rows, cols] * to_pixels
    back = render.back_depth[::factor, ::factor][rows, cols] * to_pixels
    views = [("yaw", 0.0)] + [(axis, sign * degrees) for axis in ("yaw", "pitch")
                              for degrees in (*FRONTAL_TURNS[1:], *TURNED_TURNS) for sign in (1.0, -1.0)]
    masks = []
    for axis, degrees in views:
        # Yaw keeps each pixel's row and spreads its solid segment along the row; pitch, along the column.
        along, across = (cols, rows) if axis == "yaw" else (rows, cols)
        sign = 1.0 if axis == "yaw" else -1.0
        silhouette = _rasterised_segments(along, across, front, back, np.deg2rad(degrees) * sign)
        masks.append(_normalised_mask(silhouette if axis == "yaw" else silhouette.T))
    return Hypotheses(masks=np.array(masks, dtype=np.float32), axes=tuple(a for a, _ in views), turns=np.array([d for _, d in views]))


def _rasterised_segments(along: np.ndarray, across: np.ndarray, front: np.ndarray, back: np.ndarray, angle: float) -> np.ndarray:
    """Mask (one row per ``across`` line) covered by each pixel's front-to-back segment turned by ``angle``.

    A pixel's solid column between ``back`` and ``front`` projects, after the turn, to
    an interval on its own line; intervals are filled with a running sum of +1 / -1 marks.
    """
    cos, sin = np.cos(angle), np.sin(angle)
    ends = np.stack([(along + 0.5) * cos + back * sin, (along + 0.5) * cos + front * sin])
    # A pixel's own width after the turn, at least half a pixel so edge-on slabs leave no gaps.
    half_pixel = 0.5 * max(abs(cos), 0.5)
    start, stop = ends.min(axis=0) - half_pixel, ends.max(axis=0) + half_pixel
    offset = np.floor(start.min()) - 1
    first = np.floor(start - offset).astype(int)
    last = np.floor(stop - offset).astype(int)
    marks = np.zeros((across.max() + 1, last.max() + 2), np.int32)
    np.add.at(marks, (across, first), 1)
    np.add.at(marks, (across, last + 1), -1)
    return np.cumsum(marks, axis=1) > 0


def _normalised_mask(mask: np.ndarray, image_angle: float = 0.0) -> np.ndarray:
    """Coverage on the GRID: turned by ``-image_angle``, centroid at the centre, fixed area.

    The mask is first shrunk by area averaging so thin parts (a neck, a wing) keep
    partial coverage instead of vanishing between samples.
    """
    ys, xs = np.nonzero(mask)
    scale = min(1.0, NORMALISED_ROOT_AREA / np.sqrt(xs.size))
    box = mask[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1].astype(np.float32)
    size = (max(1, round(box.shape[1] * scale)), max(1, round(box.shape[0] * scale)))
    small = cv2.resize(box, size, interpolation=cv2.INTER_AREA)
    weights = small.sum()
    grid_y, grid_x = np.mgrid[: small.shape[0], : small.shape[1]]
    centre = np.array([(grid_x * small).sum(), (grid_y * small).sum()]) / weights
    cos, sin = np.cos(-image_angle), np.sin(-image_angle)
    rotation = np.array([[cos, -sin], [sin, cos]])
    linear = rotation * (NORMALISED_ROOT_AREA / np.sqrt(weights))
    offset = GRID / 2.0 - 0.5 - linear @ centre
    matrix = np.hstack([linear, offset[:, None]]).astype(np.float32)
    return cv2.warpAffine(small, matrix, (GRID, GRID), flags=cv2.INTER_LINEAR, borderValue=0.0)
