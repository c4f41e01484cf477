"""Alignment of the template renders to the object mask (paper, section 3.2.1).

The template is scaled, rotated and shifted onto the object's silhouette: a coarse
sweep over rotation (and a few scales) keeps the candidate with the best mask
overlap, then a gradient-free search refines all four parameters by maximising the
mutual information between the warped template and the object (masks, plus grey
images when given), as the paper's "rigid registration based on mutual information".
No mirror candidates are tried: templates are symmetric about their vertical axis.
When the template is mirror-symmetric and the object clearly is too, the template's
axis must land on the object's mirror axis: a plane whose span exceeds its length
otherwise overlays best turned by 90 degrees, its fuselage along the wings.

Everything here is in pixel coordinates: (x, y) = (col, row), y pointing down,
pixel centres at integers (the same convention as ``cv2.warpAffine``).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import cv2
import numpy as np
from scipy.optimize import minimize

from frontal3d.errors import InputError

#: Grid size (pixels across) of the coarse sweep and first MI refinement; the final
#: refinement runs at the object's own resolution, up to MAX_FINE_GRID.
COARSE_GRID = 64
MAX_FINE_GRID = 256
#: Rotation step of the coarse sweep.
ANGLE_STEP = np.deg2rad(6.0)
#: Scales tried around the area-ratio estimate in the coarse sweep.
SCALE_FACTORS = (0.85, 1.0, 1.15)
#: With pixels hidden (by occluders), the visible area underestimates the object's: the sweep
#: also tries larger scales, each this factor above the last, up to the scale that would
#: fill the hidden pixels near the object too (at most MAX_HIDDEN_SCALE times the estimate).
HIDDEN_SCALE_STEP = 1.15
MAX_HIDDEN_SCALE = 1.5
#: ... and, the visible centroid being off the object's, every candidate is moved to the
#: shift (within this fraction of the sweep's grid) that best overlays the seen pixels.
HIDDEN_SHIFT_REACH = 0.3
#: How many of the best coarse candidates get an MI refinement.
REFINED_CANDIDATES = 3
#: Mirror IoU (a mask against its reflection) above which an object counts as mirror-symmetric;
#: shared airplane planforms score 0.86-0.99 about their fuselage, at most 0.59 across it.
SYMMETRIC_MIRROR_IOU = 0.85
#: The same for templates, which are symmetric by construction (airplanes, guitars: 1.0);
#: a car's side view is not, though a sedan's scores 0.84 about its vertical axis.
SYMMETRIC_TEMPLATE_MIRROR_IOU = 0.97
#: How much more symmetric the object must be about its own axis than about the placed
#: template's axis before the placement is redone along the object's axis.
AXIS_MISMATCH_MARGIN = 0.15
#: Step of the sweep for the object's mirror axis, the grid it runs on, and how far the
#: redone refinement may turn away from that axis.
AXIS_STEP = np.deg2rad(2.0)
MIRROR_GRID = 128
AXIS_WINDOW = np.deg2rad(10.0)


@dataclass(frozen=True)
class Similarity:
    """Maps TEMPLATE pixel coordinates to IMAGE pixel coordinates: p' = scale * R(angle) p + t.

    ``R(angle) = [[cos, -sin], [sin, cos]]`` acts on (x, y) with y pointing down, so a
    positive angle turns the template clockwise as seen on screen.
    """

    scale: float
    angle: float
    tx: float
    ty: float

    @property
    def matrix(self) -> np.ndarray:
        """The 2x3 float64 matrix ``[s R | t]``, ready for ``cv2.warpAffine``."""
        c, s = np.cos(self.angle) * self.scale, np.sin(self.angle) * self.scale
        return np.array([[c, -s, self.tx], [s, c, self.ty]], dtype=np.float64)

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Map (N, 2) template points (x, y) to image points."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        m = self.matrix
        return points @ m[:, :2].T + m[:, 2]

    def inverse(self) -> Similarity:
        """The image -> template similarity."""
        inv_scale = 1.0 / self.scale
        c, s = np.cos(-self.angle) * inv_scale, np.sin(-self.angle) * inv_scale
        tx = -(c * self.tx - s * self.ty)
        ty = -(s * self.tx + c * self.ty)
        return Similarity(inv_scale, -self.angle, float(tx), float(ty))

    def compose(self, first: Similarity) -> Similarity:
        """``self after first``: the similarity applying ``first``, then ``self``."""
        t = self.apply(np.array([[first.tx, first.ty]]))[0]
        angle = float(np.angle(np.exp(1j * (self.angle + first.angle))))
        return Similarity(self.scale * first.scale, angle, float(t[0]), float(t[1]))

    def to_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}

    @staticmethod
    def about(template_point: np.ndarray, image_point: np.ndarray, scale: float, angle: float) -> Similarity:
        """The similarity with this scale and angle that sends ``template_point`` to ``image_point``."""
        rotated = Similarity(scale, angle, 0.0, 0.0).apply(np.asarray(template_point))[0]
        t = np.asarray(image_point, dtype=np.float64) - rotated
        return Similarity(float(scale), float(angle), float(t[0]), float(t[1]))


def warp_mask(mask: np.ndarray, sim: Similarity, out_shape: tuple[int, int]) -> np.ndarray:
    """Template mask -> bool mask on the image grid (nearest neighbour, outside = False)."""
    src = np.ascontiguousarray(mask, dtype=np.uint8)
    out = cv2.warpAffine(src, sim.matrix, (int(out_shape[1]), int(out_shape[0])), flags=cv2.INTER_NEAREST,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return out > 0


def placed_off_grid(mask: np.ndarray, sim: Similarity, shape: tuple[int, int]) -> int:
    """How many pixels of ``mask`` placed by ``sim`` fall off the ``shape`` grid (:func:`warp_mask` drops them)."""
    ys, xs = np.nonzero(mask)
    if not len(ys):
        return 0
    corners = sim.apply(np.array([[xs.min(), ys.min()], [xs.max(), ys.min()], [xs.min(), ys.max()], [xs.max(), ys.max()]], float))
    low = np.floor(corners.min(axis=0) - 1).astype(int)
    high = np.ceil(corners.max(axis=0) + 1).astype(int)
    if (low >= 0).all() and (high <= [shape[1] - 1, shape[0] - 1]).all():
        return 0
    canvas = warp_mask(mask, Similarity(1.0, 0.0, float(-low[0]), float(-low[1])).compose(sim), (int(high[1] - low[1] + 1), int(high[0] - low[0] + 1)))
    on_grid = canvas[max(0, -low[1]) : max(0, shape[0] - low[1]), max(0, -low[0]) : max(0, shape[1] - low[0])]
    return int(np.count_nonzero(canvas) - np.count_nonzero(on_grid))


def warp_labels(labels: np.ndarray, sim: Similarity, out_shape: tuple[int, int], fill: int = -1) -> np.ndarray:
    """Template label map (e.g. regions, -1 outside) -> int32 labels on the image grid, nearest neighbour."""
    src = np.ascontiguousarray(labels, dtype=np.float32)
    out = cv2.warpAffine(src, sim.matrix, (int(out_shape[1]), int(out_shape[0])), flags=cv2.INTER_NEAREST,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=float(fill))
    return np.rint(out).astype(np.int32)


def align_template(template_mask: np.ndarray, object_mask: np.ndarray,
                   template_grey: np.ndarray | None = None, object_grey: np.ndarray | None = None,
                   max_angle: float = np.pi, hidden: np.ndarray | None = None) -> tuple[Similarity, dict]:
    """Find the template -> image similarity that best overlays the template on the object.

    ``max_angle`` bounds the in-plane rotation searched (radians, either way), for
    families whose objects are always near upright. ``hidden`` (bool, the object mask's
    shape) marks pixels whose membership is unknown (under occluders): they do not vote in
    the sweep or the mutual information, so a template part under an arm costs nothing and
    the seen outline alone places it (an arm along a guitar's neck must not shrink the
    template onto the body); the sweep then also tries larger scales and shifts. Returns the similarity and
    diagnostics: ``iou`` (full-resolution mask overlap), ``mutual_information``
    (nats, at the refinement grid), ``coarse_iou`` (best candidate of the sweep),
    ``placed_on_mirror_axis`` (the placement was redone along the object's mirror axis) and
    ``seconds``.
    """
    start = time.perf_counter()
    template_mask = _checked_mask(template_mask, "template mask")
    object_mask = _checked_mask(object_mask, "object mask")
    if not 0.0 <= max_angle <= np.pi:
        raise InputError(f"max_angle must be within [0, pi], got {max_angle}")
    tpl = _MapPyramid(_intensity_map(template_mask, template_grey, "template"))
    obj = _MapPyramid(_intensity_map(object_mask, object_grey, "object"))
    seen = None if hidden is None else _MapPyramid((~_checked_shape(hidden, object_mask.shape)).astype(np.float32))
    bins = 2 if template_grey is None and object_grey is None else 16

    tpl_centroid, tpl_area, tpl_axis = mask_moments(template_mask)
    obj_centroid, obj_area, obj_axis = mask_moments(object_mask)
    scale0 = float(np.sqrt(obj_area / tpl_area))
    obj_radius = _max_radius(object_mask, obj_centroid)
    tpl_radius = _max_radius(template_mask, tpl_centroid) * scale0
    half_side = 1.15 * max(obj_radius, tpl_radius) + 2.0
    scale_factors, window, coarse_grid = SCALE_FACTORS, half_side, COARSE_GRID
    if seen is not None:
        # The window takes in the largest scale's template, on a grid as fine as usual.
        scale_factors = _hidden_scale_factors(object_mask, hidden, obj_centroid, half_side)
        window = 1.15 * max(obj_radius, tpl_radius * scale_factors[-1]) + 2.0
        coarse_grid = int(np.ceil(COARSE_GRID * window / half_side))

    coarse = _GridView(obj, obj_centroid, window, coarse_grid, seen)
    candidates = _coarse_candidates(tpl, coarse, tpl_centroid, obj_centroid, scale0,
                                    _sweep_angles(obj_axis - tpl_axis, max_angle), scale_factors)
    coarse_iou = candidates[0][0]

    refined = [_refine_mi(tpl, coarse, bins, sim, tpl_centroid, max_angle, xtol=0.2)
               for _, sim in candidates[:REFINED_CANDIDATES]]
    best_mi, best = max(refined, key=lambda r: r[0])
    angle_window = None
    axis_angle = _mismatched_mirror_axis(template_mask, tpl_centroid, object_mask, obj_centroid, half_side, best.angle)
    if axis_angle is not None:
        on_axis = _turns_onto(axis_angle, max_angle)
        if on_axis:
            angle_window = AXIS_WINDOW
            candidates = _coarse_candidates(tpl, coarse, tpl_centroid, obj_centroid, scale0, on_axis, scale_factors)
            best_mi, best = max((_refine_mi(tpl, coarse, bins, sim, tpl_centroid, max_angle, xtol=0.2, angle_window=angle_window)
                                 for _, sim in candidates), key=lambda r: r[0])
    fine_grid = int(np.clip(np.ceil(2.0 * window), coarse_grid, MAX_FINE_GRID))
    fine = _GridView(obj, obj_centroid, window, fine_grid, seen)
    best_mi, best = _refine_mi(tpl, fine, bins, best, tpl_centroid, max_angle, xtol=0.05, angle_window=angle_window)

    warped = warp_mask(template_mask, best, object_mask.shape)
    inter = np.count_nonzero(warped & object_mask)
    union = np.count_nonzero(warped | object_mask)
    diagnostics = {
        "iou": float(inter / union),
        "mutual_information": float(best_mi),
        "coarse_iou": float(coarse_iou),
        "placed_on_mirror_axis": angle_window is not None,
        "seconds": time.perf_counter() - start,
    }
    return best, diagnostics


def _checked_mask(mask: np.ndarray, what: str) -> np.ndarray:
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise InputError(f"{what} must be a 2D array, got shape {mask.shape}")
    mask = mask > 0
    if not mask.any():
        raise InputError(f"{what} is empty")
    return mask


def _checked_shape(hidden: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    hidden = np.asarray(hidden)
    if hidden.shape != shape:
        raise InputError(f"hidden mask has shape {hidden.shape}, the object mask {shape}")
    return hidden > 0


def _hidden_scale_factors(object_mask: np.ndarray, hidden: np.ndarray, centroid: np.ndarray, half_side: float) -> tuple[float, ...]:
    """The sweep's scale factors when pixels are hidden: the usual ones, then larger ones up to
    the scale at which the object would also fill the hidden pixels within the sweep's window."""
    rows, cols = np.ogrid[: object_mask.shape[0], : object_mask.shape[1]]
    window = (np.abs(cols - centroid[0]) <= half_side) & (np.abs(rows - centroid[1]) <= half_side)
    seen_area = np.count_nonzero(object_mask & ~hidden)
    possible = np.count_nonzero((object_mask | hidden) & window)
    largest = min(MAX_HIDDEN_SCALE, float(np.sqrt(possible / max(seen_area, 1))))
    factors = list(SCALE_FACTORS)
    while factors[-1] * HIDDEN_SCALE_STEP <= SCALE_FACTORS[-1] * largest:
        factors.append(factors[-1] * HIDDEN_SCALE_STEP)
    return tuple(factors)


def _intensity_map(mask: np.ndarray, grey: np.ndarray | None, what: str) -> np.ndarray:
    """Mask as float32 in [0, 1]; with a grey image, the object's grey rescaled to [0.25, 1].

    Keeping the object's values above 0.25 keeps the silhouette itself visible to the
    mutual information even where the grey image is dark.
    """
    if grey is None:
        return mask.astype(np.float32)
    grey = np.asarray(grey, dtype=np.float32)
    if grey.shape != mask.shape:
        raise InputError(f"{what} grey image has shape {grey.shape}, its mask has {mask.shape}")
    inside = grey[mask]
    lo, hi = float(inside.min()), float(inside.max())
    norm = (grey - lo) / (hi - lo) if hi > lo else np.ones_like(grey)
    return np.where(mask, 0.25 + 0.75 * np.clip(norm, 0.0, 1.0), 0.0).astype(np.float32)


def _mirror_iou(mask: np.ndarray, centre: np.ndarray, axis_angle: float) -> float:
    """IoU of a bool mask with its reflection about the line through ``centre`` along the
    template's vertical axis turned by ``axis_angle`` (direction (-sin, cos))."""
    direction = np.array([-np.sin(axis_angle), np.cos(axis_angle)])
    reflection = 2.0 * np.outer(direction, direction) - np.eye(2)
    matrix = np.column_stack([reflection, centre - reflection @ centre])
    mirrored = cv2.warpAffine(mask.astype(np.uint8), matrix, (mask.shape[1], mask.shape[0]), flags=cv2.INTER_NEAREST,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0) > 0
    return np.count_nonzero(mask & mirrored) / max(np.count_nonzero(mask | mirrored), 1)


def _mismatched_mirror_axis(template_mask: np.ndarray, tpl_centroid: np.ndarray, object_mask: np.ndarray,
                            obj_centroid: np.ndarray, half_side: float, placed_angle: float) -> float | None:
    """The rotation that puts a mirror-symmetric template's axis on the object's mirror axis,
    when the placement at ``placed_angle`` missed that axis; None when it did not, or when
    the template or the object is not clearly symmetric (a car's side view)."""
    if _mirror_iou(template_mask, tpl_centroid, 0.0) < SYMMETRIC_TEMPLATE_MIRROR_IOU:
        return None
    view = _GridView(_MapPyramid(object_mask.astype(np.float32)), obj_centroid, half_side, MIRROR_GRID)
    grid_mask = view.object.reshape(MIRROR_GRID, MIRROR_GRID) > 0.5
    centre = np.full(2, (MIRROR_GRID - 1) / 2.0)
    axes = np.arange(0.0, np.pi, AXIS_STEP)
    scores = np.array([_mirror_iou(grid_mask, centre, a) for a in axes])
    best = int(np.argmax(scores))
    placed = _mirror_iou(grid_mask, centre, placed_angle)
    if scores[best] < SYMMETRIC_MIRROR_IOU or scores[best] - placed < AXIS_MISMATCH_MARGIN:
        return None
    return float(axes[best])


def mask_moments(mask: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Centroid (x, y), area in pixels and principal-axis angle (pixel frame) of a mask."""
    m = cv2.moments(mask.astype(np.uint8), binaryImage=True)
    centroid = np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])
    axis = 0.5 * np.arctan2(2.0 * m["mu11"], m["mu20"] - m["mu02"])
    return centroid, float(m["m00"]), float(axis)


def _max_radius(mask: np.ndarray, centroid: np.ndarray) -> float:
    rows, cols = np.nonzero(mask)
    return float(np.sqrt(((cols - centroid[0]) ** 2 + (rows - centroid[1]) ** 2).max())) + 1.0


class _MapPyramid:
    """Gaussian pyramid of a float map, so warps that shrink it do not alias.

    Level ``l`` pixel (x, y) sits at full-resolution (2^l x, 2^l y) (cv2.pyrDown samples
    the even pixels).
    """

    def __init__(self, image: np.ndarray):
        self.levels = [image]
        while min(self.levels[-1].shape) >= 32:
            self.levels.append(cv2.pyrDown(self.levels[-1]))

    def warp(self, full_to_grid: np.ndarray, grid: int) -> np.ndarray:
        """Resample onto a grid x grid image through a 2x3 full-resolution -> grid affine map."""
        scale = np.sqrt(abs(np.linalg.det(full_to_grid[:, :2])))
        level = int(np.clip(np.floor(-np.log2(max(scale, 1e-9)) + 1e-9), 0, len(self.levels) - 1))
        m = full_to_grid.copy()
        m[:, :2] *= 2.0 ** level
        return cv2.warpAffine(self.levels[level], m, (grid, grid), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)


class _GridView:
    """A square window around the object, resampled to ``grid`` pixels: where scores are computed.

    ``seen`` (1 where the object's membership is known) weights each grid pixel's vote; None: all vote.
    """

    def __init__(self, obj: _MapPyramid, centre: np.ndarray, half_side: float, grid: int, seen: _MapPyramid | None = None):
        self.grid = grid
        self.image_to_grid = Similarity.about(centre, np.full(2, (grid - 1) / 2.0), grid / (2.0 * half_side), 0.0)
        self.object = obj.warp(self.image_to_grid.matrix, grid).ravel()
        self.seen = None if seen is None else np.clip(seen.warp(self.image_to_grid.matrix, grid).ravel(), 0.0, 1.0)
        self._padded_seen: tuple[np.ndarray, np.ndarray] | None = None
        self.object_seen_area = 0.0  # set with the padded maps

    def padded_seen(self) -> tuple[np.ndarray, np.ndarray]:
        """The seen object pixels and the seen pixels (float32 0/1), padded by the shift reach."""
        if self._padded_seen is None:
            reach = int(HIDDEN_SHIFT_REACH * self.grid)
            seen = (self.seen > 0.5).reshape(self.grid, self.grid)
            object_seen = seen & (self.object > 0.5).reshape(self.grid, self.grid)
            self.object_seen_area = float(np.count_nonzero(object_seen))
            self._padded_seen = tuple(cv2.copyMakeBorder(m.astype(np.float32), reach, reach, reach, reach, cv2.BORDER_CONSTANT, value=0.0)
                                      for m in (object_seen, seen))
        return self._padded_seen

    def template(self, tpl: _MapPyramid, sim: Similarity) -> np.ndarray:
        return tpl.warp(self.image_to_grid.compose(sim).matrix, self.grid).ravel()


def _sweep_angles(axis_angle: float, max_angle: float) -> list[float]:
    """The coarse sweep's rotations: a regular step within ``max_angle``, plus the two that
    turn the template's principal axis onto the object's."""
    n_steps = int(np.floor(max_angle / ANGLE_STEP))
    return list(ANGLE_STEP * np.arange(-n_steps, n_steps + 1)) + _turns_onto(axis_angle, max_angle)


def _turns_onto(axis_angle: float, max_angle: float) -> list[float]:
    """The rotations by ``axis_angle`` and by it plus a half turn, wrapped to (-pi, pi],
    that stay within ``max_angle``: both ways of laying the template's axis on a line."""
    wrapped = (float(np.angle(np.exp(1j * a))) for a in (axis_angle, axis_angle + np.pi))
    return [a for a in wrapped if abs(a) <= max_angle]


def _coarse_candidates(tpl: _MapPyramid, view: _GridView, tpl_centroid: np.ndarray, obj_centroid: np.ndarray,
                       scale0: float, angles: list[float], scale_factors: tuple[float, ...] = SCALE_FACTORS) -> list[tuple[float, Similarity]]:
    """Overlap-ranked (IoU, similarity) candidates, angles at least 15 degrees apart: centroids
    matched, or with hidden pixels (``view.seen``) shifted to the best IoU over the seen pixels."""
    obj_in = view.object > 0.5
    scored = []
    for angle in angles:
        for factor in scale_factors:
            sim = Similarity.about(tpl_centroid, obj_centroid, scale0 * factor, angle)
            tpl_in = view.template(tpl, sim) > 0.5
            if view.seen is None:
                union = np.count_nonzero(tpl_in | obj_in)
                scored.append((np.count_nonzero(tpl_in & obj_in) / max(union, 1), sim))
            else:
                iou, (dx, dy) = _best_seen_shift(tpl_in, view)
                grid_px = 1.0 / view.image_to_grid.scale
                scored.append((iou, Similarity(sim.scale, sim.angle, sim.tx + dx * grid_px, sim.ty + dy * grid_px)))
    scored.sort(key=lambda s: -s[0])
    kept: list[tuple[float, Similarity]] = []
    for iou, sim in scored:
        if all(abs(np.angle(np.exp(1j * (sim.angle - k.angle)))) > np.deg2rad(15) for _, k in kept):
            kept.append((iou, sim))
    return kept


def _best_seen_shift(template_in: np.ndarray, view: _GridView) -> tuple[float, tuple[int, int]]:
    """The shift (dx, dy), in grid pixels within HIDDEN_SHIFT_REACH of the grid, of the template
    that maximises its IoU with the object over the seen pixels, and that IoU (correlations)."""
    object_seen, seen = view.padded_seen()
    template = template_in.reshape(view.grid, view.grid).astype(np.float32)
    inter = cv2.matchTemplate(object_seen, template, cv2.TM_CCORR)  # [dy + reach, dx + reach]
    template_seen = cv2.matchTemplate(seen, template, cv2.TM_CCORR)
    iou = inter / np.maximum(template_seen + view.object_seen_area - inter, 1.0)
    dy, dx = np.unravel_index(int(np.argmax(iou)), iou.shape)
    reach = (iou.shape[0] - 1) // 2
    return float(iou[dy, dx]), (int(dx) - reach, int(dy) - reach)


def _mutual_information(tpl_values: np.ndarray, obj_bins: np.ndarray, obj_counts: np.ndarray, bins: int,
                        weights: np.ndarray | None = None) -> float:
    """MI of the joint histogram; template values are split linearly between neighbouring bins.

    The linear split makes the score vary smoothly with sub-pixel moves, which the
    gradient-free optimiser needs; the object side is fixed, so hard bins suffice.
    ``weights`` (per pixel, None = 1) scale each pixel's count; ``obj_counts`` must be weighted alike.
    """
    t = tpl_values * (bins - 1)
    if bins == 2:  # a soft mask: its upper-bin column is a weighted count, the lower one the rest
        upper = np.bincount(obj_bins, weights=t if weights is None else t * weights, minlength=2)
        joint = np.stack([obj_counts - upper, upper], axis=1)
    else:
        low = np.minimum(np.floor(t), bins - 2).astype(np.intp)
        frac = t - low
        idx = obj_bins * bins + low
        shares = np.concatenate([1.0 - frac, frac]) if weights is None else np.concatenate([(1.0 - frac) * weights, frac * weights])
        joint = np.bincount(np.concatenate([idx, idx + 1]), shares, minlength=bins * bins).reshape(bins, bins)
    joint = joint / joint.sum()
    p_obj, p_tpl = joint.sum(axis=1, keepdims=True), joint.sum(axis=0, keepdims=True)
    nz = joint > 0
    return float(np.sum(joint[nz] * np.log(joint[nz] / (p_obj @ p_tpl)[nz])))


def _refine_mi(tpl: _MapPyramid, view: _GridView, bins: int, start: Similarity, tpl_centroid: np.ndarray,
               max_angle: float, xtol: float, angle_window: float | None = None) -> tuple[float, Similarity]:
    """Powell search of (log scale, angle, shift) maximising MI, rotating about the template centroid.
    ``angle_window`` keeps the angle that close to the start's (a placement fixed to the mirror axis).

    Parameters are expressed in grid pixels of displacement at the object's rim, so one
    unit of each moves the silhouette by about one grid pixel.
    """
    obj_bins = np.rint(view.object * (bins - 1)).astype(np.intp)
    obj_counts = np.bincount(obj_bins, weights=view.seen, minlength=bins).astype(np.float64)
    grid_px = 1.0 / view.image_to_grid.scale
    rim = 0.4 * view.grid
    centre = start.apply(tpl_centroid[None])[0]

    def similarity(x: np.ndarray) -> Similarity:
        return Similarity.about(tpl_centroid, centre + x[2:] * grid_px, start.scale * np.exp(x[0] / rim),
                                start.angle + x[1] / rim)

    def cost(x: np.ndarray) -> float:
        return -_mutual_information(view.template(tpl, similarity(x)), obj_bins, obj_counts, bins, view.seen)

    low, high = (-np.inf, np.inf) if max_angle >= np.pi else (-max_angle - start.angle, max_angle - start.angle)
    if angle_window is not None:
        low, high = max(low, -angle_window), min(high, angle_window)
    angle_bounds = tuple(None if np.isinf(b) else b * rim for b in (low, high))
    reach = view.grid / 4.0  # the start is within a few grid pixels; this keeps line searches sane
    bounds = [(-np.log(2.0) * rim, np.log(2.0) * rim), angle_bounds, (-reach, reach), (-reach, reach)]
    result = minimize(cost, np.zeros(4), method="Powell", bounds=bounds,
                      options={"xtol": xtol, "ftol": 1e-5, "maxfev": 400})
    if view.seen is not None and result.fun > cost(np.zeros(4)):
        # Bounded Powell can end worse than it began; on the few seen pixels of a partly
        # hidden object it does (an arm over a third of a guitar: MI 0.23 -> 0.04).
        result.x, result.fun = np.zeros(4), cost(np.zeros(4))
    best = similarity(result.x)
    best = Similarity(best.scale, float(np.angle(np.exp(1j * best.angle))), best.tx, best.ty)
    return -float(result.fun), best
