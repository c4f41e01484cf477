"""Mirror-symmetry evidence for the frontal gate (issue #6): has the object turned about its axis?

Seen in its canonical view, a plane's planform is mirror-symmetric about the fuselage
and a guitar's face nearly so about the neck. Turned about that axis (image-up) by
30° or more, the object stays about as long and its outline stays plausible, but it
loses the symmetry: a plane's fin sticks out to one side and the engines and wing
tips on the near and far side shift by different amounts; a guitar shows its side
rim along one edge only. The silhouette test cannot see this, because a narrower
object of the same kind explains the outline just as well.

The object's best mirror line is searched near the axis of the aligned template
(the similarity found by the silhouette alignment carries the template's axis onto
the image), and its mirror agreement is compared with the template's own: a template
that is itself asymmetric (an electric guitar's cutaway) sets a lower bar. Families
switch it on with ``mirror_margin``; guitars do not, since real guitar bodies (basses,
single cutaways) are less symmetric than the templates even when seen straight on.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from frontal3d.render import TemplateRenders
from frontal3d.stages.align import Similarity
from frontal3d.stages.turned_views import content_key

#: Side of the square grid on which mirror agreement is measured. Agreement is counted on
#: whole pixels (the turned mask thresholded at one half): soft edges made a level plane's thin
#: wings read only 0.89-0.97 symmetric, as much loss as a 10-degree roll, so the margin had to
#: be loose enough to let rolled planes through (docs/results.md, "mirror agreement on whole pixels").
#: A 192 grid with the object filling 0.8 of it keeps thin wings several pixels wide.
GRID = 192
#: Share of the grid the object's longest side spans (room for turned lines).
FILL = 0.8
#: Tilts (degrees) of the template's own mirror line searched about its vertical axis.
TEMPLATE_TILTS = tuple(range(-4, 5, 2))
#: Tilts (degrees) of the object's mirror line searched about the aligned template's axis.
OBJECT_TILTS = tuple(range(-10, 11, 2))
#: How far (share of the grid) the mirror line may sit from the silhouette's centroid.
OFFSET_LIMIT = 0.15
#: Bends of the object's mirror line tried: sideways offset of its ends (t = ±1) against its
#: middle, as a share of the object's length. A slightly bent photo of a straight object, or
#: a bent neck, must not read as a turn; the template's line stays straight. Bends of 0.08 changed
#: nothing on synthetic planes (seeds 80, 81) and let rolled real planes' wing shift pass as a bend.
OBJECT_BENDS = (-0.04, 0.0, 0.04)
_TEMPLATE_CACHE: dict[str, tuple[float, float]] = {}
_SQUARE = np.ones((3, 3), np.uint8)
_CACHE_LIMIT = 32


@dataclass(frozen=True)
class MirrorEvidence:
    """Best mirror IoU of the object's silhouette and of its aligned template's."""

    object_iou: float
    template_iou: float

    @property
    def asymmetry(self) -> float:
        """How much less mirror-symmetric the object is than its template (positive: less)."""
        return self.template_iou - self.object_iou


def mirror_evidence(object_mask: np.ndarray, render: TemplateRenders, similarity: Similarity) -> MirrorEvidence:
    """Compare the object's mirror symmetry with the template's, about the template's axis as aligned."""
    template_iou, template_tilt = template_mirror(render)
    # The similarity turns the template clockwise on screen by its angle; tilts here count
    # counter-clockwise, so the template's line lands at its own tilt minus that angle.
    axis = np.deg2rad(template_tilt) - similarity.angle
    object_iou, _ = best_mirror(object_mask, axis, OBJECT_TILTS, OBJECT_BENDS)
    return MirrorEvidence(object_iou=object_iou, template_iou=template_iou)


def template_mirror(render: TemplateRenders) -> tuple[float, float]:
    """(best mirror IoU, tilt in degrees) of the template about its vertical axis; cached by content."""
    key = content_key(render)
    if key not in _TEMPLATE_CACHE:
        if len(_TEMPLATE_CACHE) >= _CACHE_LIMIT:
            _TEMPLATE_CACHE.pop(next(iter(_TEMPLATE_CACHE)))
        _TEMPLATE_CACHE[key] = best_mirror(render.mask, 0.0, TEMPLATE_TILTS)
    return _TEMPLATE_CACHE[key]


@dataclass(frozen=True)
class MirrorFit:
    """The best mirror line found on a mask: its agreement, its direction and where it runs.

    ``to_grid`` carries image pixels (x, y, 1) onto the search grid, on which the line is
    vertical; on grid row y it runs at column ``doubled_columns[y] / 2`` (a bent line
    runs at its own column on each row), so the mirror image of grid column x is
    ``doubled_columns[y] - x``.
    """

    agreement: float
    tilt_deg: float
    to_grid: np.ndarray
    doubled_columns: np.ndarray

    def partners(self, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Every image pixel's mirror image, as float32 x and y maps for ``cv2.remap``."""
        x, y, line = self._on_grid(shape)
        mirrored_x = 2.0 * line - x
        back = np.linalg.inv(self.to_grid)
        return ((back[0, 0] * mirrored_x + back[0, 1] * y + back[0, 2]).astype(np.float32),
                (back[1, 0] * mirrored_x + back[1, 1] * y + back[1, 2]).astype(np.float32))

    def distance_to_line(self, shape: tuple[int, int]) -> np.ndarray:
        """Every image pixel's distance from the line, in image pixels."""
        x, _, line = self._on_grid(shape)
        return np.abs(x - line) / np.hypot(self.to_grid[0, 0], self.to_grid[0, 1])

    def _on_grid(self, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every image pixel's grid column and row, and the line's column on that row."""
        rows, cols = np.indices(shape, dtype=np.float64)
        x = self.to_grid[0, 0] * cols + self.to_grid[0, 1] * rows + self.to_grid[0, 2]
        y = self.to_grid[1, 0] * cols + self.to_grid[1, 1] * rows + self.to_grid[1, 2]
        line = self.doubled_columns[np.clip(np.round(y).astype(int), 0, len(self.doubled_columns) - 1)] / 2.0
        return x, y, line


def best_mirror(mask: np.ndarray, axis: float, tilts_deg: tuple[int, ...], bends: tuple[float, ...] = (0.0,)) -> tuple[float, float]:
    """Best IoU of ``mask`` with its mirror image over lines at ``axis`` (radians from image-up,
    counter-clockwise on screen) plus each tilt, each bent like a parabola by each of
    ``bends`` (see :data:`OBJECT_BENDS`), and the winning tilt in degrees (relative to image-up)."""
    fit = fit_mirror(mask, axis, tilts_deg, bends)
    return fit.agreement, fit.tilt_deg


def fit_mirror(mask: np.ndarray, axis: float, tilts_deg: Iterable[float], bends: tuple[float, ...] = (0.0,),
               outline: bool = False, grid: int = GRID) -> MirrorFit:
    """The mirror line of :func:`best_mirror`, with where it runs; ``outline`` scores the
    outline's agreement with its mirror image instead of the area's; ``grid`` is the search
    grid's side (finer places the line more exactly, at a cost).

    For each direction the mask is turned so the line is vertical and cut to whole pixels
    (see :data:`GRID`); the overlap of every row with its own reflection about every column
    is one autocorrelation, done by FFT, and a bent line reads each row's overlap at its own column.
    An outline is a band of three grid pixels: a blob stuck to the object adds area on one
    side only, but along the object's own outline the two sides still match.
    """
    small, to_small = _cropped(mask, grid)
    ys, xs = np.nonzero(small > 0.5)
    centre = (float(xs.mean()), float(ys.mean()))
    scale = grid * FILL / max(small.shape)
    # Mirror columns c near the centre, as indices 2c into the autocorrelation.
    doubled = np.arange(round(2 * (grid / 2 - 0.5 - OFFSET_LIMIT * grid)), round(2 * (grid / 2 - 0.5 + OFFSET_LIMIT * grid)) + 1)
    rows = np.arange(grid)
    best: MirrorFit | None = None
    for tilt in tilts_deg:
        direction = axis + np.deg2rad(tilt)
        turn = upright_turn(centre, direction, grid, scale)
        upright = cv2.warpAffine(small, turn[:2], (grid, grid), flags=cv2.INTER_LINEAR, borderValue=0.0)
        upright = (upright > 0.5).astype(np.float32)
        occupied = np.flatnonzero(upright.sum(axis=1) > 0)
        if outline:
            upright = cv2.dilate(upright - cv2.erode(upright, _SQUARE), _SQUARE)
        spectrum = np.fft.rfft(upright, n=2 * grid, axis=1)
        overlap = np.fft.irfft(spectrum * spectrum, n=2 * grid, axis=1)  # row y, index 2c
        length = max(float(occupied[-1] - occupied[0]), 1.0)
        along = (rows - (occupied[0] + occupied[-1]) / 2.0) / (length / 2.0)
        area = upright.sum()
        for bend in bends:
            shift = np.round(2 * bend * length * (along**2 - 1.0 / 3.0)).astype(int)
            index = np.clip(doubled[:, None] + shift[None, :], 0, 2 * grid - 1)
            inter = overlap[rows[None, :], index].sum(axis=1)
            iou = inter / np.maximum(2 * area - inter, 1e-9)
            column = int(iou.argmax())
            if best is None or iou[column] > best.agreement:
                best = MirrorFit(float(iou[column]), float(np.rad2deg(direction)), turn @ to_small, doubled[column] + shift)
    assert best is not None, "no tilt to search"
    return best


def upright_turn(centre: tuple[float, float], direction: float, side: int, scale: float = 1.0) -> np.ndarray:
    """3x3 affine turning (and scaling) the image about ``centre`` so a line at ``direction``
    (radians from image-up, counter-clockwise on screen) is vertical, ``centre`` landing in
    the middle of a side x side canvas."""
    turn = np.vstack([cv2.getRotationMatrix2D(centre, -np.rad2deg(direction), scale), [0.0, 0.0, 1.0]])
    turn[:2, 2] += (side / 2 - centre[0], side / 2 - centre[1])
    return turn


def _cropped(mask: np.ndarray, grid: int) -> tuple[np.ndarray, np.ndarray]:
    """The mask's box with a margin, as float coverage, shrunk (area average) to at most 2 x ``grid``,
    and the 3x3 affine carrying image pixels onto it."""
    ys, xs = np.nonzero(mask)
    height, width = ys.max() - ys.min() + 1, xs.max() - xs.min() + 1
    margin = int(0.3 * max(height, width)) + 2
    box = np.zeros((height + 2 * margin, width + 2 * margin), np.float32)
    box[margin:-margin, margin:-margin] = mask[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    to_box = np.array([[1.0, 0.0, margin - xs.min()], [0.0, 1.0, margin - ys.min()], [0.0, 0.0, 1.0]])
    shrink = min(1.0, 2 * grid / max(box.shape))
    if shrink < 1.0:
        full_height, full_width = box.shape
        box = cv2.resize(box, None, fx=shrink, fy=shrink, interpolation=cv2.INTER_AREA)
        # cv2.resize's pixel centres: x_small = (x + 0.5) * f - 0.5, per axis.
        fx, fy = box.shape[1] / full_width, box.shape[0] / full_height
        to_box = np.array([[fx, 0.0, 0.5 * fx - 0.5], [0.0, fy, 0.5 * fy - 0.5], [0.0, 0.0, 1.0]]) @ to_box
    return box, to_box
