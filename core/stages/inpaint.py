"""Fill occluded object pixels region by region (paper section 3.2.6).

Each region of the object is filled only from its own visible pixels, so a guitar
body is repaired with body texture and never with fretboard or skin. Where the
region shows a large enough square of visible texture, that square is quilted into
a new texture (Efros & Freeman's image quilting: blocks chosen by overlap error and
joined along minimum-error boundary cuts) and pasted over the hole with a dilated,
feathered seam. Quilting is chosen over a feathered-tile synthesis because the cuts
follow the texture (wood grain, paint flakes) instead of blurring it, and it costs
only one small template match per block. Regions too thin for such a square (necks,
trims) are filled by exemplar inpainting in the spirit of Criminisi et al., which
propagates their structure inward patch by patch.
"""

from __future__ import annotations

import cv2
import numpy as np

from frontal3d.errors import InputError

#: The paper's 60..100 px patch sizes are meant for photos whose shorter side is at
#: least this many pixels; smaller photos get proportionally smaller patches, so a
#: 500 px photo searches for 30..50 px squares (the same share of the object).
PATCH_REFERENCE_SIDE = 1000
#: Below this side a "texture patch" holds too few texels to quilt from.
SMALLEST_PATCH = 8
#: Blocks whose overlap error is within this factor of the best are equally good;
#: picking among them at random keeps the quilt from repeating one block.
QUILT_TOLERANCE = 0.1


def scaled_patch_range(image_shape: tuple[int, ...], patch_min: int, patch_max: int) -> tuple[int, int]:
    """Patch side limits for an image of this shape (see :data:`PATCH_REFERENCE_SIDE`)."""
    factor = min(1.0, min(image_shape[:2]) / PATCH_REFERENCE_SIDE)
    low = max(SMALLEST_PATCH, int(round(patch_min * factor)))
    high = max(low, int(round(patch_max * factor)))
    return low, high


def largest_square(mask: np.ndarray, max_side: int | None = None) -> tuple[int, int, int] | None:
    """Top row, left column and side of the largest axis-aligned square inside ``mask``.

    The chessboard distance to the nearest outside pixel is the half-side of the
    largest square centred on each pixel, so one distance transform finds it.
    ``max_side`` caps the side (the square stays centred on the same pixel).
    Returns None for an empty mask.
    """
    if not mask.any():
        return None
    padded = np.pad(mask.astype(np.uint8), 1)
    distance = cv2.distanceTransform(padded, cv2.DIST_C, 3)[1:-1, 1:-1]
    row, col = np.unravel_index(int(np.argmax(distance)), distance.shape)
    side = 2 * int(distance[row, col]) - 1
    if max_side is not None:
        side = min(side, max_side)
    return int(row) - side // 2, int(col) - side // 2, side


def _min_error_cut(error: np.ndarray) -> np.ndarray:
    """Per row, the first column of the new block along the cheapest top-to-bottom seam."""
    rows, cols = error.shape
    cumulative = error.astype(np.float64).copy()
    for r in range(1, rows):
        previous = cumulative[r - 1]
        left = np.concatenate(([np.inf], previous[:-1]))
        right = np.concatenate((previous[1:], [np.inf]))
        cumulative[r] += np.minimum(np.minimum(left, previous), right)
    seam = np.empty(rows, dtype=np.int64)
    seam[-1] = int(np.argmin(cumulative[-1]))
    for r in range(rows - 2, -1, -1):
        c = seam[r + 1]
        lo, hi = max(0, c - 1), min(cols, c + 2)
        seam[r] = lo + int(np.argmin(cumulative[r, lo:hi]))
    return seam


def quilt(exemplar: np.ndarray, out_shape: tuple[int, int], rng: np.random.Generator,
          needed: np.ndarray | None = None) -> np.ndarray:
    """Synthesize an ``out_shape`` texture from a square ``exemplar`` by image quilting.

    ``needed`` (bool, ``out_shape``) lets the caller skip blocks it will never use:
    a block is only placed where it touches a needed pixel, and only its placed
    neighbours constrain it. Pixels of skipped blocks are zero. Blocks are half the
    exemplar with a quarter-block overlap: wide enough overlaps to keep stripes
    continuous, while still offering (side / 2)^2 candidate blocks.
    """
    exemplar = exemplar.astype(np.float32)
    side = exemplar.shape[0]
    block = max(4, side // 2)
    overlap = max(3, block // 4)
    step = block - overlap
    out_h, out_w = out_shape
    n_rows = max(1, -(-(out_h - overlap) // step))
    n_cols = max(1, -(-(out_w - overlap) // step))
    canvas = np.zeros((n_rows * step + overlap, n_cols * step + overlap, 3), np.float32)
    placed = np.zeros((n_rows, n_cols), bool)
    if needed is not None:
        padded = np.zeros(canvas.shape[:2], bool)
        padded[:out_h, :out_w] = needed
        per_block = cv2.boxFilter(padded.astype(np.float32), -1, (block, block), normalize=False,
                                  anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
        wanted = per_block[::step, ::step][:n_rows, :n_cols] > 0
    else:
        wanted = np.ones((n_rows, n_cols), bool)
    n_candidates = side - block + 1

    def overlap_cost(strip: np.ndarray) -> np.ndarray:
        return cv2.matchTemplate(exemplar, strip, cv2.TM_SQDIFF)[:n_candidates, :n_candidates]

    for i in range(n_rows):
        for j in range(n_cols):
            if not wanted[i, j]:
                continue
            y, x = i * step, j * step
            has_left = j > 0 and placed[i, j - 1]
            has_top = i > 0 and placed[i - 1, j]
            cost = np.zeros((n_candidates, n_candidates), np.float32)
            if has_left:
                cost += overlap_cost(canvas[y:y + block, x:x + overlap])
            if has_top:
                cost += overlap_cost(canvas[y:y + overlap, x:x + block])
            if has_left and has_top:
                cost -= overlap_cost(canvas[y:y + overlap, x:x + overlap])
                # A sum of squares, but the subtraction's rounding can dip below zero, and a
                # negative minimum would put the threshold below every candidate.
                np.maximum(cost, 0.0, out=cost)
            threshold = cost.min() * (1.0 + QUILT_TOLERANCE) + 1e-6
            choices = np.flatnonzero(cost.ravel() <= threshold)
            py, px = np.unravel_index(int(rng.choice(choices)), cost.shape)
            patch = exemplar[py:py + block, px:px + block]
            old = canvas[y:y + block, x:x + block]
            take_new = np.ones((block, block), bool)
            if has_left:
                seam = _min_error_cut(((old[:, :overlap] - patch[:, :overlap]) ** 2).sum(-1))
                take_new[:, :overlap] &= np.arange(overlap)[None, :] >= seam[:, None]
            if has_top:
                seam = _min_error_cut(((old[:overlap] - patch[:overlap]) ** 2).sum(-1).T)
                take_new[:overlap, :] &= np.arange(overlap)[:, None] >= seam[None, :]
            canvas[y:y + block, x:x + block] = np.where(take_new[..., None], patch, old)
            placed[i, j] = True
    return canvas[:out_h, :out_w]


def _bounding_box(mask: np.ndarray, margin: int) -> tuple[slice, slice]:
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    h, w = mask.shape
    return (slice(max(0, rows[0] - margin), min(h, rows[-1] + 1 + margin)),
            slice(max(0, cols[0] - margin), min(w, cols[-1] + 1 + margin)))


def _quilt_fill(out: np.ndarray, hole: np.ndarray, region: np.ndarray, square: tuple[int, int, int],
                rng: np.random.Generator) -> None:
    """Quilt a texture from ``square`` over ``hole`` and paste it with a feathered seam."""
    top, left, side = square
    exemplar = out[top:top + side, left:left + side]
    seam_width = max(2, int(round(side / 12)))
    rows, cols = _bounding_box(hole, seam_width)
    hole_crop = hole[rows, cols]
    region_crop = region[rows, cols]
    distance = cv2.distanceTransform((~hole_crop).astype(np.uint8), cv2.DIST_L2, 3)
    alpha = np.clip(1.0 - distance / seam_width, 0.0, 1.0) * region_crop
    texture = quilt(exemplar, hole_crop.shape, rng, needed=alpha > 0)
    crop = out[rows, cols]
    out[rows, cols] = crop + alpha[..., None].astype(np.float32) * (texture - crop)


def _exemplar_fill(out: np.ndarray, hole: np.ndarray, source: np.ndarray, half: int) -> bool:
    """Fill ``hole`` patch by patch from fully visible patches of ``source`` (Criminisi-style).

    Priority = confidence x data term on the fill front; the data term uses the
    isophotes of the visible texture, smoothed once into the hole, so edges are
    continued before flat areas. Returns False when ``source`` holds no whole patch.
    """
    n_labels, labels = cv2.connectedComponents(hole.astype(np.uint8), connectivity=8)
    region_rows, region_cols = _bounding_box(source | hole, 0)
    for label in range(1, n_labels):
        component = labels == label
        patch_half = half
        while True:
            for margin in (12 * (2 * patch_half + 1), max(hole.shape)):
                near_rows, near_cols = _bounding_box(component, margin)
                rows = slice(max(near_rows.start, region_rows.start), min(near_rows.stop, region_rows.stop))
                cols = slice(max(near_cols.start, region_cols.start), min(near_cols.stop, region_cols.stop))
                size = 2 * patch_half + 1
                src = source[rows, cols]
                if min(src.shape) < size:
                    continue
                whole = cv2.boxFilter(src.astype(np.float32), -1, (size, size), normalize=False,
                                      borderType=cv2.BORDER_CONSTANT)
                valid = whole[patch_half:src.shape[0] - patch_half, patch_half:src.shape[1] - patch_half] >= size * size - 0.5
                if valid.any():
                    break
            else:
                if patch_half == 1:
                    return False
                patch_half = max(1, patch_half // 2)
                continue
            break
        _exemplar_fill_crop(out[rows, cols], component[rows, cols], src, valid, patch_half)
    return True


def _exemplar_fill_crop(image: np.ndarray, to_fill: np.ndarray, source: np.ndarray, valid: np.ndarray,
                        half: int) -> None:
    size = 2 * half + 1
    h, w = to_fill.shape
    known = source.copy()
    to_fill = to_fill.copy()
    confidence = known.astype(np.float32)
    grey = image.mean(axis=2)
    weight = cv2.GaussianBlur(known.astype(np.float32), (0, 0), half)
    grey_filled = np.where(known, grey, cv2.GaussianBlur(grey * known, (0, 0), half) / np.maximum(weight, 1e-6))
    gx = cv2.Sobel(grey_filled, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8)
    gy = cv2.Sobel(grey_filled, cv2.CV_32F, 0, 1, ksize=3, scale=1 / 8)
    reliable = cv2.erode(known.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(np.float32)
    smooth_weight = np.maximum(cv2.boxFilter(reliable, -1, (size, size)), 1e-6)
    isophote_x = -cv2.boxFilter(gy * reliable, -1, (size, size)) / smooth_weight
    isophote_y = cv2.boxFilter(gx * reliable, -1, (size, size)) / smooth_weight
    candidate_cost = np.where(valid, 0.0, np.inf).astype(np.float32)
    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)
    while to_fill.any():
        front = to_fill & (cv2.dilate(known.astype(np.uint8), cross) > 0)
        if not front.any():
            front = to_fill
        known_f = known.astype(np.float32)
        patch_confidence = cv2.boxFilter(confidence * known_f, -1, (size, size), borderType=cv2.BORDER_CONSTANT)
        nx = cv2.Sobel(known_f, cv2.CV_32F, 1, 0, ksize=3)
        ny = cv2.Sobel(known_f, cv2.CV_32F, 0, 1, ksize=3)
        norm = np.maximum(np.hypot(nx, ny), 1e-6)
        data = np.abs(isophote_x * nx + isophote_y * ny) / norm / 255.0 + 1e-3
        priority = np.where(front, patch_confidence * data, -1.0)
        r, c = np.unravel_index(int(np.argmax(priority)), priority.shape)
        r = int(np.clip(r, half, h - half - 1))
        c = int(np.clip(c, half, w - half - 1))
        window = (slice(r - half, r + half + 1), slice(c - half, c + half + 1))
        target = image[window]
        target_known = known[window]
        if target_known.any():
            mask = np.repeat(target_known[..., None], 3, axis=2).astype(np.float32)
            cost = cv2.matchTemplate(image, target, cv2.TM_SQDIFF, mask=mask) + candidate_cost
        else:
            cost = candidate_cost
        sr, sc = np.unravel_index(int(np.argmin(cost)), cost.shape)
        fill_here = to_fill[window]
        image[window][fill_here] = image[sr:sr + size, sc:sc + size][fill_here]
        confidence[window][fill_here] = patch_confidence[r, c]
        known[window] |= fill_here
        to_fill[window] &= ~fill_here


def inpaint_regions(image: np.ndarray, region_map: np.ndarray, fill_mask: np.ndarray,
                    patch_min: int = 60, patch_max: int = 100, seed: int = 0) -> np.ndarray:
    """Fill the ``fill_mask`` pixels of each region using only that region's other pixels.

    Per region: quilt from the largest visible square (side ``patch_min``..``patch_max``,
    scaled by :func:`scaled_patch_range`), else exemplar inpainting from the region's
    visible patches. A region with no visible pixel at all has no colour of its own;
    it is filled by OpenCV's Telea inpainting from the object around it (never from
    what lies beyond the regions: an arm reaching past the object). Pixels of
    ``fill_mask`` outside every region (``region_map == -1``) are left unchanged.
    Returns a new uint8 image; the input is not modified.
    """
    image = np.asarray(image)
    region_map = np.asarray(region_map)
    fill_mask = np.asarray(fill_mask, dtype=bool)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise InputError(f"inpaint: image must be H x W x 3 uint8, got {image.shape} {image.dtype}")
    if region_map.shape != image.shape[:2] or fill_mask.shape != image.shape[:2]:
        raise InputError(f"inpaint: region map {region_map.shape} and fill mask {fill_mask.shape} "
                         f"must match the image size {image.shape[:2]}")
    rng = np.random.default_rng(seed)
    low, high = scaled_patch_range(image.shape, patch_min, patch_max)
    exemplar_half = max(4, low // 12)  # 9 x 9 (Criminisi's size) up to 11 x 11 for 1 Mpx photos
    out = image.astype(np.float32)
    without_colour = np.zeros(fill_mask.shape, bool)
    for label in np.unique(region_map[fill_mask & (region_map >= 0)]):
        region = region_map == label
        hole = fill_mask & region
        source = region & ~fill_mask
        square = largest_square(source, max_side=high)
        if square is not None and square[2] >= low:
            _quilt_fill(out, hole, region, square, rng)
        elif not source.any() or not _exemplar_fill(out, hole, source, exemplar_half):
            without_colour |= hole
    result = np.clip(np.rint(out), 0, 255).astype(np.uint8)
    if without_colour.any():
        # Telea propagates the colours bordering its mask: pixels outside every region are
        # masked too, so only the object's own (visible or already filled) pixels spread.
        unknown = without_colour | (region_map < 0)
        result[without_colour] = cv2.inpaint(result, unknown.astype(np.uint8), 3, cv2.INPAINT_TELEA)[without_colour]
    return result
