"""Silhouette warping (paper 3.2.4): bend the template renders onto the object's mask.

The deformation is Moving Least Squares (Schaefer, McPhail, Warren 2006) driven by
boundary correspondences. It is evaluated as an *inverse* map (for every output pixel,
where in the template it comes from) so the warped maps have no holes, and front and
back renders go through the same map so they keep one shared silhouette. A final
fitting step makes the warped maps cover the object mask exactly: MLS only pins the
pivots, so between them a few boundary pixels would otherwise fall just outside the
template.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from frontal3d.errors import ConfigError, InputError, TemplateError
from frontal3d.render import MAP_NAMES

MLS_KINDS = ("similarity", "rigid")

#: Keys a template-map dict must hold for :func:`warp_template_to_silhouette`.
TEMPLATE_MAP_KEYS = MAP_NAMES

#: Entries of the N x p weight matrix evaluated at once: bounds MLS memory (~100 MB).
_TILE_ELEMENTS = 1 << 22

#: Squared distance below which a pixel counts as sitting on a pivot: its weight is
#: capped instead of infinite, so the map there is the pivot's target (to ~1e-6 px).
_MIN_SQUARED_DISTANCE = 1e-8


@dataclass
class WarpResult:
    """Template maps carried onto the object's image grid.

    ``front_depth``/``back_depth`` are in the template's world units (the mesher
    rescales Z with ``local_scale``), finite exactly on ``mask`` and NaN elsewhere.
    Normals are unit vectors on ``mask`` and 0 elsewhere (as in ``TemplateRenders``);
    region maps hold labels on ``mask`` and -1 elsewhere.
    ``source_coords[r, c]`` is the template-grid pixel (x=col, y=row) that the smooth
    MLS + similarity map sends to image pixel (r, c) (defined on the whole grid; pixels
    it sends outside the template took their values from the nearest template pixel).
    ``local_scale`` is image pixels per template pixel of that map, locally (smoothed).
    """

    mask: np.ndarray
    front_depth: np.ndarray
    back_depth: np.ndarray
    front_normals: np.ndarray
    back_normals: np.ndarray
    front_regions: np.ndarray
    back_regions: np.ndarray
    source_coords: np.ndarray
    local_scale: np.ndarray


def _check_pivots(out_pivots: np.ndarray, src_pivots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    out_pivots = np.asarray(out_pivots, dtype=np.float64)
    src_pivots = np.asarray(src_pivots, dtype=np.float64)
    if out_pivots.ndim != 2 or out_pivots.shape[1] != 2 or out_pivots.shape != src_pivots.shape:
        raise ValueError(
            f"pivots must be two (p, 2) arrays of equal length, got {out_pivots.shape} and {src_pivots.shape}"
        )
    if not (np.isfinite(out_pivots).all() and np.isfinite(src_pivots).all()):
        raise InputError("MLS pivots contain NaN or infinite coordinates")
    if len(np.unique(out_pivots, axis=0)) < 2:
        raise InputError("MLS needs at least two distinct boundary pivots; the silhouette is degenerate")
    return out_pivots, src_pivots


def _mls_at(
    points: np.ndarray, out_pivots: np.ndarray, src_pivots: np.ndarray, alpha: float, rigid: bool
) -> np.ndarray:
    """MLS map of ``points`` (n, 2), pivots already centred; one BLAS product per tile.

    The best similarity per point is the complex factor c = sum w conj(p^) q^ / sum w |p^|^2
    (p^, q^ = pivots relative to their weighted centroids); expanding the centroids turns
    every sum into ``weights @ per-pivot column``, so a tile costs a few elementwise
    passes over its n x p weights plus one matrix product.
    """
    px, py = out_pivots[:, 0], out_pivots[:, 1]
    qx, qy = src_pivots[:, 0], src_pivots[:, 1]
    columns = np.stack(
        [np.ones_like(px), px, py, qx, qy, px * qx + py * qy, px * qy - py * qx, px * px + py * py], axis=1
    )
    result = np.empty_like(points)
    tile = max(1, _TILE_ELEMENTS // len(px))
    for start in range(0, len(points), tile):
        vx = points[start : start + tile, 0:1]
        vy = points[start : start + tile, 1:2]
        weights = np.square(px[None, :] - vx)
        weights += np.square(py[None, :] - vy)
        np.maximum(weights, _MIN_SQUARED_DISTANCE, out=weights)
        if alpha == 1.0:
            np.reciprocal(weights, out=weights)
        else:
            np.power(weights, -alpha, out=weights)
        sums = weights @ columns
        total = sums[:, 0]
        psx, psy = sums[:, 1] / total, sums[:, 2] / total
        qsx, qsy = sums[:, 3] / total, sums[:, 4] / total
        real = sums[:, 5] - total * (psx * qsx + psy * qsy)
        imag = sums[:, 6] - total * (psx * qsy - psy * qsx)
        spread = np.maximum(sums[:, 7] - total * (psx * psx + psy * psy), np.finfo(np.float64).tiny)
        c = (real + 1j * imag) / spread
        if rigid:
            c = np.exp(1j * np.angle(c))
        mapped = c * ((vx[:, 0] - psx) + 1j * (vy[:, 0] - psy)) + (qsx + 1j * qsy)
        result[start : start + tile, 0] = mapped.real
        result[start : start + tile, 1] = mapped.imag
    return result


def mls_inverse_map(
    out_pivots: np.ndarray,
    src_pivots: np.ndarray,
    out_shape: tuple[int, int],
    alpha: float = 1.0,
    kind: str = "similarity",
    grid_step: int = 1,
) -> np.ndarray:
    """For every pixel of an ``out_shape`` grid, the source (x, y) it comes from.

    MLS with ``out_pivots[i]`` -> ``src_pivots[i]``: each output pixel gets the
    similarity (or rotation, ``kind="rigid"``) that best maps the pivots, weighted by
    1 / distance^(2 alpha). With ``grid_step`` > 1 the map is evaluated every
    ``grid_step`` pixels and bilinearly upsampled: MLS is smooth, so this costs little
    accuracy and saves ``grid_step``^2 in time. Returns (H, W, 2) float32.
    """
    if kind not in MLS_KINDS:
        raise ConfigError(f"MLS kind must be one of {MLS_KINDS}, got {kind!r}")
    if not alpha > 0:
        raise ConfigError(f"MLS alpha must be positive, got {alpha}")
    if int(grid_step) < 1:
        raise ConfigError(f"MLS grid_step must be >= 1, got {grid_step}")
    out_pivots, src_pivots = _check_pivots(out_pivots, src_pivots)
    height, width = int(out_shape[0]), int(out_shape[1])
    grid_step = int(grid_step)

    # Centre both pivot sets: keeps the expanded sums of _mls_at free of cancellation.
    out_centre = out_pivots.mean(axis=0)
    src_centre = src_pivots.mean(axis=0)
    coarse_rows = grid_step * np.arange(-(-(height - 1) // grid_step) + 1)
    coarse_cols = grid_step * np.arange(-(-(width - 1) // grid_step) + 1)
    grid_x, grid_y = np.meshgrid(coarse_cols, coarse_rows)
    points = np.stack([grid_x.ravel(), grid_y.ravel()], axis=1).astype(np.float64) - out_centre
    mapped = _mls_at(points, out_pivots - out_centre, src_pivots - src_centre, float(alpha), kind == "rigid")
    coarse = (mapped + src_centre).reshape(len(coarse_rows), len(coarse_cols), 2)
    if grid_step == 1:
        return coarse.astype(np.float32)
    return _upsample_bilinear(coarse, grid_step, height, width).astype(np.float32)


def _upsample_bilinear(coarse: np.ndarray, step: int, height: int, width: int) -> np.ndarray:
    """Bilinear interpolation of a map sampled at multiples of ``step`` onto every pixel."""
    rows = np.arange(height) / step
    cols = np.arange(width) / step
    r0 = np.clip(np.floor(rows).astype(np.intp), 0, max(coarse.shape[0] - 2, 0))
    c0 = np.clip(np.floor(cols).astype(np.intp), 0, max(coarse.shape[1] - 2, 0))
    r1 = np.minimum(r0 + 1, coarse.shape[0] - 1)
    c1 = np.minimum(c0 + 1, coarse.shape[1] - 1)
    fr = (rows - r0)[:, None, None]
    fc = (cols - c0)[None, :, None]
    top = coarse[r0][:, c0] * (1 - fc) + coarse[r0][:, c1] * fc
    bottom = coarse[r1][:, c0] * (1 - fc) + coarse[r1][:, c1] * fc
    return top * (1 - fr) + bottom * fr


def _nearest_index(source_coords: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    rows = np.clip(np.rint(source_coords[..., 1]), 0, shape[0] - 1).astype(np.intp)
    cols = np.clip(np.rint(source_coords[..., 0]), 0, shape[1] - 1).astype(np.intp)
    return rows, cols


def _fill_invalid_with_nearest(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Copy of ``values`` where every invalid pixel holds its nearest valid pixel's value."""
    if valid.all():
        return values
    nearest = ndimage.distance_transform_edt(~valid, return_distances=False, return_indices=True)
    return values[nearest[0], nearest[1]]


def warp_maps(maps: dict[str, np.ndarray], source_coords: np.ndarray, nearest: set[str]) -> dict[str, np.ndarray]:
    """Sample each (H_s, W_s[, C]) map at ``source_coords`` (H, W, 2), (x, y) per pixel.

    Maps named in ``nearest`` (labels) take the nearest source pixel. Other maps are
    sampled bilinearly; their NaNs (e.g. depth outside the template) are first filled
    with the nearest valid value so they cannot bleed into valid pixels, and an output
    pixel is NaN only where its nearest source pixel was NaN. Sources off the grid
    read the grid's edge.
    """
    source_coords = np.asarray(source_coords, dtype=np.float32)
    map_x = np.ascontiguousarray(source_coords[..., 0])
    map_y = np.ascontiguousarray(source_coords[..., 1])
    warped: dict[str, np.ndarray] = {}
    for name, values in maps.items():
        values = np.asarray(values)
        rows, cols = _nearest_index(source_coords, values.shape)
        if name in nearest:
            warped[name] = values[rows, cols]
            continue
        finite = np.isfinite(values)
        valid = finite if values.ndim == 2 else finite.all(axis=-1)
        if not valid.any():
            warped[name] = np.full(source_coords.shape[:2] + values.shape[2:], np.nan, dtype=np.float32)
            continue
        filled = np.ascontiguousarray(_fill_invalid_with_nearest(values, valid), dtype=np.float32)
        channels = [filled] if filled.ndim == 2 or filled.shape[2] <= 4 else np.moveaxis(filled, -1, 0)
        sampled = [
            cv2.remap(np.ascontiguousarray(c), map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            for c in channels
        ]
        result = sampled[0] if len(sampled) == 1 else np.stack(sampled, axis=-1)
        result = result.reshape(source_coords.shape[:2] + values.shape[2:])
        result[~valid[rows, cols]] = np.nan
        warped[name] = result
    return warped


#: Sides (template pixels) of the footprints :func:`fit_silhouette` keeps ridges over.
RIDGE_WINDOWS = (1, 3, 5, 9, 17, 33)


def footprint_windows(source_coords: np.ndarray) -> np.ndarray:
    """Per output pixel, the side of the smallest of ``RIDGE_WINDOWS`` that covers the
    square of template pixels the pixel stands for (its source spacing to its neighbours)."""
    step_x = np.hypot(*np.gradient(source_coords[..., 0]))
    step_y = np.hypot(*np.gradient(source_coords[..., 1]))
    spacing = np.maximum(step_x, step_y)
    windows = np.asarray(RIDGE_WINDOWS)
    return windows[np.minimum(np.searchsorted(windows, spacing), len(windows) - 1)]


def keep_ridges(depth: np.ndarray, valid: np.ndarray, window: int, highest: bool) -> np.ndarray:
    """``depth`` with each valid pixel replaced by the highest (or lowest) valid depth in a
    ``window``-square around it.

    Where the warp shrinks the template, one output pixel stands for several template
    pixels but samples only one point among them: a part a pixel or two wide seen
    edge-on (an airplane's fin from above) was kept or lost depending on where that
    point fell, so its height, and with it the object's depth extent, changed with
    sub-pixel shifts of the alignment or vanished where the warp squeezes the template.
    The highest front (lowest back) depth under the footprint keeps such parts whole;
    on smooth surfaces it moves depth by at most the slope over half a window.
    """
    if window <= 1:
        return depth
    padded = np.where(valid, depth, -np.inf if highest else np.inf).astype(np.float32)
    extreme = (ndimage.maximum_filter if highest else ndimage.minimum_filter)(padded, size=window, mode="nearest")
    return np.where(valid, extreme, np.nan).astype(np.float32)


def fit_silhouette(
    object_mask: np.ndarray, template_maps: dict[str, np.ndarray], source_coords: np.ndarray
) -> dict[str, np.ndarray]:
    """Warp the template maps so that they cover ``object_mask`` exactly.

    Object pixels whose source lies outside the template (MLS only pins the pivots, so
    a sliver of the boundary can miss) read the nearest template pixel instead; pixels
    outside the object are cleared (depth NaN, normals 0, regions -1). Returns the
    warped ``TEMPLATE_MAP_KEYS`` maps, ``mask`` being ``object_mask`` itself.
    """
    object_mask = np.asarray(object_mask, dtype=bool)
    template_valid = (
        np.asarray(template_maps["mask"], dtype=bool)
        & np.isfinite(template_maps["front_depth"])
        & np.isfinite(template_maps["back_depth"])
    )
    if not template_valid.any():
        raise TemplateError("template renders have no pixel with both a front and a back depth")

    rows, cols = _nearest_index(source_coords, template_valid.shape)
    height, width = template_valid.shape
    on_grid = (
        (source_coords[..., 0] >= -0.5)
        & (source_coords[..., 0] < width - 0.5)
        & (source_coords[..., 1] >= -0.5)
        & (source_coords[..., 1] < height - 0.5)
    )
    misses = object_mask & ~(on_grid & template_valid[rows, cols])
    sample_coords = np.array(source_coords, dtype=np.float32)
    if misses.any():
        nearest = ndimage.distance_transform_edt(~template_valid, return_distances=False, return_indices=True)
        sample_coords[misses, 0] = nearest[1][rows[misses], cols[misses]]
        sample_coords[misses, 1] = nearest[0][rows[misses], cols[misses]]

    float_maps = {}
    for name in ("front_depth", "back_depth", "front_normals", "back_normals"):
        values = np.array(template_maps[name], dtype=np.float32)
        values[~template_valid] = np.nan
        float_maps[name] = values
    windows = footprint_windows(source_coords)
    used = [int(w) for w in np.unique(windows[object_mask]) if w > 1]
    for name, highest in (("front_depth", True), ("back_depth", False)):
        for window in used:
            float_maps[f"{name}@{window}"] = keep_ridges(float_maps[name], template_valid, window, highest)
    label_maps = {name: np.asarray(template_maps[name]) for name in ("front_regions", "back_regions")}
    warped = warp_maps({**float_maps, **label_maps}, sample_coords, nearest=set(label_maps))
    for name in ("front_depth", "back_depth"):
        for window in used:
            warped[name] = np.where(windows == window, warped.pop(f"{name}@{window}"), warped[name])

    fitted: dict[str, np.ndarray] = {"mask": object_mask.copy()}
    for name in ("front_depth", "back_depth"):
        fitted[name] = np.where(object_mask, warped[name], np.nan).astype(np.float32)
    for name in ("front_normals", "back_normals"):
        normals = warped[name]
        length = np.linalg.norm(normals, axis=-1, keepdims=True)
        unit = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
        fitted[name] = np.where(object_mask[..., None], unit, 0.0).astype(np.float32)
    for name in ("front_regions", "back_regions"):
        fitted[name] = np.where(object_mask, warped[name], -1).astype(np.int32)
    return fitted


def local_scale_of(source_coords: np.ndarray, smoothing_sigma: float = 2.0) -> np.ndarray:
    """Image pixels per template pixel of the forward map, from the inverse map.

    The forward map's area factor is 1 / det(J) of the inverse map ``source_coords``
    (finite differences); its square root is the in-plane scale the mesher applies to
    depth. The determinant is smoothed first so pixel-level noise does not ripple Z.
    """
    dx_dcol = np.gradient(source_coords[..., 0], axis=1)
    dx_drow = np.gradient(source_coords[..., 0], axis=0)
    dy_dcol = np.gradient(source_coords[..., 1], axis=1)
    dy_drow = np.gradient(source_coords[..., 1], axis=0)
    area = np.abs(dx_dcol * dy_drow - dx_drow * dy_dcol).astype(np.float64)
    if smoothing_sigma > 0:
        area = ndimage.gaussian_filter(area, smoothing_sigma, mode="nearest")
    return (1.0 / np.sqrt(np.maximum(area, 1e-12))).astype(np.float32)


def warp_template_to_silhouette(
    object_mask: np.ndarray,
    template_maps: dict[str, np.ndarray],
    template_to_image: np.ndarray,
    out_pivots: np.ndarray,
    src_pivots: np.ndarray,
    alpha: float = 1.0,
    kind: str = "similarity",
    grid_step: int = 2,
    max_scale_change: float = 2.0,
) -> WarpResult:
    """Warp front/back template renders onto ``object_mask`` with one shared map.

    ``template_to_image`` (2x3) is the alignment similarity, template pixel -> image
    pixel. ``src_pivots`` are template boundary points already mapped by it into the
    image; ``out_pivots`` are the object boundary points they match. MLS runs in the
    image frame; the inverse similarity then turns its result into template-grid
    coordinates.
    """
    object_mask = np.asarray(object_mask)
    if object_mask.ndim != 2:
        raise InputError(f"object mask must be a 2D array, got shape {object_mask.shape}")
    object_mask = object_mask.astype(bool)
    if not object_mask.any():
        raise InputError("object mask is empty: nothing to warp the template onto")
    missing = [key for key in TEMPLATE_MAP_KEYS if key not in template_maps]
    if missing:
        raise TemplateError(f"template renders lack maps {missing}")
    similarity = np.asarray(template_to_image, dtype=np.float64)
    if similarity.shape != (2, 3) or not np.isfinite(similarity).all():
        raise ValueError(f"template_to_image must be a finite 2x3 matrix, got shape {similarity.shape}")
    linear = similarity[:, :2]
    if not max_scale_change >= 1.0:
        raise ConfigError(f"max_scale_change must be at least 1, got {max_scale_change}")
    if abs(np.linalg.det(linear)) < 1e-12:
        raise InputError("the template-to-image alignment is degenerate (zero scale)")

    image_coords = mls_inverse_map(out_pivots, src_pivots, object_mask.shape, alpha, kind, grid_step)
    image_to_template = np.linalg.inv(linear).T
    source_coords = ((image_coords.astype(np.float64) - similarity[:, 2]) @ image_to_template).astype(np.float32)
    fitted = fit_silhouette(object_mask, template_maps, source_coords)
    local_scale = local_scale_of(source_coords)
    typical = float(np.median(local_scale[object_mask]))
    local_scale = np.clip(local_scale, typical / max_scale_change, typical * max_scale_change)
    return WarpResult(**fitted, source_coords=source_coords, local_scale=local_scale)
