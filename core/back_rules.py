"""How a family textures the side of the object the photo cannot see (paper 3.2.6, 4.1).

Every rule has the same signature::

    rule(front_texture, mask, region_map, region_names, params) -> back_texture

and returns an image of the front's shape in the BACK view's own pixel frame: the
view from behind, which is the front frame mirrored left-right (so the back
silhouette is ``np.fliplr(mask)``). Pixels outside that silhouette are 0; the
texture stage bleeds colours into them. Families pick a rule by name in their
settings (``back_texture``, ``back_texture_params``); plugins add rules with the
``frontal3d_back_texture_rules`` hook, next to :data:`BUILTIN_BACK_RULES`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from frontal3d.errors import ConfigError, InputError
from frontal3d.stages.inpaint import SMALLEST_PATCH, largest_square, quilt, scaled_patch_range

BackRule = Callable[[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...], dict[str, Any]], np.ndarray]


def _region_pixels(mask: np.ndarray, region_map: np.ndarray, region_names: tuple[str, ...],
                   params: dict[str, Any]) -> np.ndarray:
    """Pixels of ``params['region']`` (default: the first region, the main body).

    The whole object stands in when this photo shows none of the region's pixels.
    """
    name = params.get("region", region_names[0] if region_names else None)
    if name is None:
        return mask
    if name not in region_names:
        raise ConfigError(f"back_texture_params.region: unknown region {name!r} (regions: {', '.join(region_names)})")
    pixels = (region_map == region_names.index(name)) & mask
    return pixels if pixels.any() else mask


def _check(front_texture: np.ndarray, mask: np.ndarray) -> None:
    if front_texture.ndim != 3 or front_texture.shape[:2] != mask.shape:
        raise InputError(f"back texture: front texture {front_texture.shape} does not match the mask {mask.shape}")
    if not mask.any():
        raise InputError("back texture: the object mask is empty")


def mirror_front(front_texture: np.ndarray, mask: np.ndarray, region_map: np.ndarray,
                 region_names: tuple[str, ...], params: dict[str, Any]) -> np.ndarray:
    """The hidden side looks like the visible one (cars, trees, animals seen from the side).

    Seen from behind, the front image appears mirrored, so the back view of a
    symmetric object is exactly the front texture flipped left-right.
    """
    _check(front_texture, mask)
    return np.where(np.fliplr(mask)[..., None], np.fliplr(front_texture), 0).astype(front_texture.dtype)


def solid_from_region(front_texture: np.ndarray, mask: np.ndarray, region_map: np.ndarray,
                      region_names: tuple[str, ...], params: dict[str, Any]) -> np.ndarray:
    """The whole back in the mean colour of one region (``params['region']``): plain painted backs."""
    _check(front_texture, mask)
    colour = front_texture[_region_pixels(mask, region_map, region_names, params)].mean(axis=0)
    back = np.zeros_like(front_texture)
    back[np.fliplr(mask)] = np.rint(colour).astype(front_texture.dtype)
    return back


def synthesize_from_region(front_texture: np.ndarray, mask: np.ndarray, region_map: np.ndarray,
                           region_names: tuple[str, ...], params: dict[str, Any]) -> np.ndarray:
    """The whole back quilted from the largest square of one region (the paper's guitar rule).

    ``params['region']`` names the region (e.g. "body"); optional ``patch_max``
    (default 100, scaled for small images like the inpainting patches) caps the
    square and ``seed`` fixes the synthesis. A region too thin for any texture
    square falls back to its mean colour. The square avoids the region's sharp
    edges (:func:`_plain_square`): quilted, an f-hole or a pickup's rim in the
    sample repeats all over the back as streaks.
    """
    _check(front_texture, mask)
    pixels = _region_pixels(mask, region_map, region_names, params)
    _, high = scaled_patch_range(front_texture.shape, SMALLEST_PATCH, int(params.get("patch_max", 100)))
    square = _plain_square(front_texture, pixels, high)
    if square is None or square[2] < SMALLEST_PATCH:
        return solid_from_region(front_texture, mask, region_map, region_names, params)
    top, left, side = square
    back_mask = np.fliplr(mask)
    rows = np.flatnonzero(back_mask.any(axis=1))
    cols = np.flatnonzero(back_mask.any(axis=0))
    window = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    rng = np.random.default_rng(int(params.get("seed", 0)))
    texture = quilt(front_texture[top:top + side, left:left + side], back_mask[window].shape, rng,
                    needed=back_mask[window])
    back = np.zeros_like(front_texture)
    back[window] = np.where(back_mask[window][..., None], np.clip(np.rint(texture), 0, 255), 0)
    return back


#: Canny thresholds for the sharp edges a texture sample avoids (wood grain and
#: JPEG noise stay under them; an f-hole's or a binding's edge does not).
EDGE_THRESHOLDS = (50, 150)
#: How far (pixels) around a sharp edge the sample keeps off.
EDGE_CLEARANCE = 2


def _plain_square(texture: np.ndarray, pixels: np.ndarray, max_side: int) -> tuple[int, int, int] | None:
    """The largest square of ``pixels`` (at most ``max_side``) clear of sharp edges, when it
    is at least half as large as the largest square of ``pixels`` at all; otherwise that one."""
    square = largest_square(pixels, max_side=max_side)
    if square is None:
        return None
    grey = cv2.cvtColor(np.ascontiguousarray(texture[..., :3], dtype=np.uint8), cv2.COLOR_RGB2GRAY)
    edges = cv2.Canny(cv2.GaussianBlur(grey, (3, 3), 0), *EDGE_THRESHOLDS)
    near_edge = cv2.dilate(edges, np.ones((2 * EDGE_CLEARANCE + 1,) * 2, np.uint8)) > 0
    plain = largest_square(pixels & ~near_edge, max_side=max_side)
    if plain is not None and plain[2] >= max(SMALLEST_PATCH, square[2] // 2):
        return plain
    return square


#: Rules every family can name in its settings; plugins add more through the hook.
BUILTIN_BACK_RULES: dict[str, BackRule] = {
    "synthesize_from_region": synthesize_from_region,
    "mirror_front": mirror_front,
    "solid_from_region": solid_from_region,
}
