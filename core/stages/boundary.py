"""Boundary matching between the object's and the aligned template's silhouettes (paper, 3.2.2).

The global match is the paper's eq. (1)-(2): every input contour point gets a template
contour point, the assignment moves forward around the template by 0..k points per
step, and the sum of distances is minimal. Matching each segmented region on its own
(with a tighter K) then pins the silhouette match where regions meet the outline, so
that, e.g., a neck pixel cannot be matched to the body; the same per-region matches
on the inner region boundaries are the extra pivots of the warp (paper, 3.2.4).

All contours are (N, 2) float arrays of pixel coordinates (x, y) = (col, row) on one
image grid: the template's contour and region map must already be aligned to the
image (see :mod:`frontal3d.stages.align`).
"""

from __future__ import annotations

from typing import Iterable

import cv2
import numpy as np
from scipy.ndimage import distance_transform_edt, minimum_filter1d
from scipy.spatial.distance import cdist

from frontal3d.errors import InputError

#: The paper's jump bound k at its working resolution.
PAPER_K, PAPER_RESOLUTION = 128, 350
#: How many template starting points the cyclic matching tries by default.
DEFAULT_STARTS = 4


def default_k(working_resolution: int) -> int:
    """The paper's k = 128 at 350 px, scaled linearly with the working resolution."""
    return max(1, int(round(PAPER_K * working_resolution / PAPER_RESOLUTION)))


def trace_contour(mask: np.ndarray) -> np.ndarray:
    """Outer boundary of the mask's largest component, one point per boundary pixel.

    Orientation: counter-clockwise as seen on screen (and in the world frame, y up);
    the first point is the top-most, then left-most boundary pixel. A one-pixel-wide
    part is walked along both of its sides, so such pixels appear twice.
    """
    mask = np.asarray(mask)
    if mask.ndim != 2 or not mask.any():
        raise InputError("cannot trace a contour: the mask is empty or not 2D")
    contours, _ = cv2.findContours((mask > 0).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    largest = max(contours, key=lambda c: (cv2.contourArea(c), len(c)))
    points = largest[:, 0, :].astype(np.float64)
    x, y = points[:, 0], points[:, 1]
    twice_area = np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)  # > 0: clockwise on screen (y down)
    if twice_area > 0:
        points = points[::-1]
    first = np.lexsort((points[:, 0], points[:, 1]))[0]
    return np.roll(points, -first, axis=0)


def match_contours(input_contour: np.ndarray, template_contour: np.ndarray, k: int,
                   starts: Iterable[int] | None = None) -> np.ndarray:
    """Eq. (1)-(2): omega (m,) indices into the template contour, one per input point.

    omega advances by 0..k template points per input point, cyclically, and goes
    around the template exactly once, so the match is monotone and covers the whole
    outline. For each tried template start s = omega[0] the dynamic programme is exact,
    in O(m n) (a sliding-window minimum replaces the inner min over the k + 1 allowed
    predecessors). ``starts`` defaults to the few template points nearest to the
    first input point; pass ``range(n)`` for the exact cyclic optimum at n times the cost.
    The paper's constant +1 per step is the same for every valid match and is left out.
    """
    a = _checked_contour(input_contour, "input contour")
    b = _checked_contour(template_contour, "template contour")
    if k < 1:
        raise InputError(f"the jump bound k must be at least 1, got {k}")
    if len(a) * k < len(b):
        raise InputError(f"k={k} is too small: {len(a)} input points cannot cover {len(b)} template points")
    omega = _cyclic_match(a, b, k, starts)
    if omega is None:
        raise InputError("no template start point to try: `starts` is empty")
    return omega


def match_regions(input_regions: np.ndarray, template_regions: np.ndarray, input_contour: np.ndarray,
                  template_contour: np.ndarray, global_match: np.ndarray, K: int = 32) -> np.ndarray:
    """Section 3.2.2: refine the global silhouette match with per-region matches.

    Each region present in both maps (labels >= 0; below 0 is background) is matched
    on its own contour with the jump bound K. Its matched pairs that lie on both outer
    silhouettes (the template side within 1 px) are anchors; between consecutive
    anchors the template stretch is split evenly, as in the paper, when the anchors
    are close (up to K input points apart); longer gaps keep the shape of the global
    match, bent to meet the anchors. Without anchors the global match is returned.
    """
    a = _checked_contour(input_contour, "input contour")
    b = _checked_contour(template_contour, "template contour")
    input_regions = _checked_regions(input_regions, "input")
    template_regions = _checked_regions(template_regions, "template")
    omega = np.asarray(global_match, dtype=np.int64)
    m, n = len(a), len(b)
    if omega.shape != (m,):
        raise InputError(f"global_match has shape {omega.shape}, expected ({m},)")
    input_index = _contour_index_map(a, input_regions.shape, tolerance=0.0)
    template_index = _contour_index_map(b, template_regions.shape, tolerance=1.0)

    anchor_u, anchor_t = [], []
    for in_pts, tpl_pts in _region_pairs(input_regions, template_regions, K):
        u = _lookup(input_index, in_pts)
        t = _lookup(template_index, tpl_pts)
        keep = (u >= 0) & (t >= 0)
        anchor_u.append(u[keep])
        anchor_t.append(t[keep])
    if not anchor_u:
        return omega.copy()
    u, t = np.concatenate(anchor_u), np.concatenate(anchor_t)
    u, first = np.unique(u, return_index=True)  # one anchor per input point
    t = t[first]
    if len(u) < 2:
        return omega.copy()

    unrolled = omega[0] + np.concatenate([[0], np.cumsum((np.diff(omega) % n))])
    t = t + n * np.round((unrolled[u] - t) / n)  # the turn of the global match each anchor belongs to
    keep = _longest_non_decreasing(t)
    u, t = u[keep], t[keep]
    keep = t <= t[0] + n  # the cycle may not go round the template more than once
    u, t = u[keep], t[keep]
    if len(u) < 2:
        return omega.copy()

    refined = _fill_between_anchors(unrolled, u, t, m, n, K)
    return (np.rint(refined).astype(np.int64) % n)


def region_pivots(input_regions: np.ndarray, template_regions: np.ndarray, K: int = 32,
                  max_pairs: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Matched point pairs on the INNER region boundaries, as extra pivots for the warp.

    Uses the same per-region matching as :func:`match_regions` and keeps the pairs
    whose input and template points are both off their outer silhouette (more than
    1.5 px inside), i.e. on a boundary between two regions or around a hole region.
    Returns (input points (P, 2), template points (P, 2)), evenly subsampled to at
    most ``max_pairs``.
    """
    input_regions = _checked_regions(input_regions, "input")
    template_regions = _checked_regions(template_regions, "template")
    input_inner = distance_transform_edt(input_regions >= 0) > 1.5
    template_inner = distance_transform_edt(template_regions >= 0) > 1.5
    in_all, tpl_all = [np.zeros((0, 2))], [np.zeros((0, 2))]
    for in_pts, tpl_pts in _region_pairs(input_regions, template_regions, K):
        keep = _pixel_values(input_inner, in_pts) & _pixel_values(template_inner, tpl_pts)
        in_all.append(in_pts[keep])
        tpl_all.append(tpl_pts[keep])
    in_pts, tpl_pts = np.concatenate(in_all), np.concatenate(tpl_all)
    if len(in_pts) > max_pairs:
        pick = np.linspace(0, len(in_pts), max_pairs, endpoint=False).astype(np.intp)
        in_pts, tpl_pts = in_pts[pick], tpl_pts[pick]
    return in_pts, tpl_pts


def _checked_contour(contour: np.ndarray, what: str) -> np.ndarray:
    contour = np.asarray(contour, dtype=np.float64)
    if contour.ndim != 2 or contour.shape[1] != 2 or len(contour) == 0:
        raise InputError(f"{what} must be a non-empty (N, 2) array, got shape {contour.shape}")
    return contour


def _checked_regions(regions: np.ndarray, what: str) -> np.ndarray:
    regions = np.asarray(regions)
    if regions.ndim != 2 or not np.issubdtype(regions.dtype, np.integer):
        raise InputError(f"the {what} region map must be a 2D integer label array, got {regions.dtype} {regions.shape}")
    return regions


def _cyclic_match(a: np.ndarray, b: np.ndarray, k: int, starts: Iterable[int] | None) -> np.ndarray | None:
    """Best of the fixed-start matches over ``starts``; None when ``starts`` is empty or none admits a match."""
    n = len(b)
    distances = cdist(a, b)
    if starts is None:
        starts = _nearest_starts(distances[0], DEFAULT_STARTS)
    best_cost, best = np.inf, None
    for s in np.unique(np.asarray(list(starts), dtype=np.int64) % n):
        cost, omega = _match_from_start(distances, int(s), k)
        if cost < best_cost:
            best_cost, best = cost, omega
    return best


def _nearest_starts(first_row: np.ndarray, count: int) -> np.ndarray:
    """Template indices at the ``count`` deepest cyclic local minima of the distance to the first input point.

    Several minima matter where the outline comes back close to itself (the two sides of a neck).
    """
    is_min = (first_row <= np.roll(first_row, 1)) & (first_row <= np.roll(first_row, -1))
    minima = np.flatnonzero(is_min)
    return minima[np.argsort(first_row[minima], kind="stable")[:count]]


def _match_from_start(distances: np.ndarray, start: int, k: int) -> tuple[float, np.ndarray | None]:
    """Exact DP with omega[0] = start, on the template unrolled to start..start + n.

    Only the cost table is stored; back-tracking recovers each predecessor as the
    argmin over its k + 1 allowed cells, which is the cell the forward pass used.
    """
    m, n = distances.shape
    columns = (start + np.arange(n + 1)) % n
    d = distances[:, columns]
    table = np.empty((m, n + 1))
    table[0] = np.inf
    table[0, 0] = d[0, 0]
    origin = k // 2  # shifts scipy's centred window of k + 1 cells to [j - k, j]
    for i in range(1, m):
        table[i] = d[i] + minimum_filter1d(table[i - 1], size=k + 1, mode="constant", cval=np.inf, origin=origin)
    closing = table[m - 1, max(0, n - k):]  # the last step back to omega[0] + n must also be <= k
    end = max(0, n - k) + int(np.argmin(closing))
    cost = float(table[m - 1, end])
    if not np.isfinite(cost):
        return np.inf, None
    path = np.empty(m, dtype=np.int64)
    path[m - 1] = end
    for i in range(m - 1, 0, -1):
        j = path[i]
        lo = max(0, j - k)
        path[i - 1] = lo + int(np.argmin(table[i - 1, lo:j + 1]))
    return cost, (start + path) % n


def _region_pairs(input_regions: np.ndarray, template_regions: np.ndarray, K: int):
    """For each region in both maps: (input region contour, its matched template region points)."""
    labels = np.intersect1d(np.unique(input_regions[input_regions >= 0]),
                            np.unique(template_regions[template_regions >= 0]))
    for label in labels:
        in_contour = trace_contour(input_regions == label)
        tpl_contour = trace_contour(template_regions == label)
        if len(in_contour) * K < len(tpl_contour):
            continue  # the regions differ too much in size to be matched with this K
        omega = _cyclic_match(in_contour, tpl_contour, K, None)
        if omega is not None:
            yield in_contour, tpl_contour[omega]


def _contour_index_map(contour: np.ndarray, shape: tuple[int, ...], tolerance: float) -> np.ndarray:
    """Image of contour indices: each pixel within ``tolerance`` of the contour holds its nearest index, else -1."""
    index = np.full(shape[:2], -1, dtype=np.int64)
    pix = np.rint(contour).astype(np.intp)
    inside = (pix[:, 0] >= 0) & (pix[:, 0] < shape[1]) & (pix[:, 1] >= 0) & (pix[:, 1] < shape[0])
    pix = pix[inside]
    index[pix[::-1, 1], pix[::-1, 0]] = np.flatnonzero(inside)[::-1]  # revisited pixels keep their first index
    if tolerance <= 0:
        return index
    dist, (rows, cols) = distance_transform_edt(index < 0, return_indices=True)
    return np.where(dist <= tolerance, index[rows, cols], -1)


def _lookup(index: np.ndarray, points: np.ndarray) -> np.ndarray:
    pix = np.rint(points).astype(np.intp)
    out = np.full(len(points), -1, dtype=np.int64)
    ok = (pix[:, 0] >= 0) & (pix[:, 0] < index.shape[1]) & (pix[:, 1] >= 0) & (pix[:, 1] < index.shape[0])
    out[ok] = index[pix[ok, 1], pix[ok, 0]]
    return out


def _pixel_values(image: np.ndarray, points: np.ndarray) -> np.ndarray:
    return _lookup(image.astype(np.int64), points) > 0


def _longest_non_decreasing(values: np.ndarray) -> np.ndarray:
    """Indices of a longest non-decreasing subsequence (patience sorting, O(N log N)).

    Drops the few per-region anchors that would make the silhouette match run backwards.
    """
    tails: list[float] = []
    tail_index: list[int] = []
    parent = np.full(len(values), -1, dtype=np.int64)
    for i, v in enumerate(values):
        pos = int(np.searchsorted(tails, v, side="right"))
        if pos > 0:
            parent[i] = tail_index[pos - 1]
        if pos == len(tails):
            tails.append(v)
            tail_index.append(i)
        else:
            tails[pos] = v
            tail_index[pos] = i
    chain = []
    i = tail_index[-1]
    while i >= 0:
        chain.append(i)
        i = parent[i]
    return np.array(chain[::-1], dtype=np.int64)


def _fill_between_anchors(unrolled: np.ndarray, u: np.ndarray, t: np.ndarray, m: int, n: int, K: int) -> np.ndarray:
    """Unrolled template positions for every input point, passing through the anchors (u, t).

    Short gaps (<= K input points) are split evenly; longer ones follow the global match
    plus an offset that goes linearly from one anchor's correction to the next. The
    cycle closes through the last anchor back to the first one, one turn later.
    """
    u_ext = np.concatenate([u, [u[0] + m]])
    t_ext = np.concatenate([t, [t[0] + n]])
    global_ext = np.concatenate([unrolled, unrolled + n])
    seg = np.searchsorted(u_ext, np.arange(u[0], u[0] + m), side="right") - 1
    i = np.arange(u[0], u[0] + m)
    u0, u1, t0, t1 = u_ext[seg], u_ext[seg + 1], t_ext[seg], t_ext[seg + 1]
    frac = (i - u0) / (u1 - u0)
    even = t0 + frac * (t1 - t0)
    off0 = t0 - global_ext[u0]
    off1 = t1 - global_ext[u1]
    bent = np.clip(global_ext[i] + off0 + frac * (off1 - off0), t0, t1)
    filled = np.where(u1 - u0 <= K, even, bent)
    filled = np.maximum.accumulate(filled)
    return np.roll(filled, u[0])
