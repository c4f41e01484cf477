"""Boundary matching (paper 3.2.2, eq. 1-2) and its per-region refinement."""

import cv2
import numpy as np
import pytest

from frontal3d.errors import InputError
from frontal3d.stages.boundary import default_k, match_contours, match_regions, region_pivots, trace_contour


def cyclic_steps(omega: np.ndarray, n: int) -> np.ndarray:
    return np.diff(np.append(omega, omega[0])) % n


def match_cost(a: np.ndarray, b: np.ndarray, omega: np.ndarray) -> float:
    return float(np.linalg.norm(a - b[omega], axis=1).sum())


def brute_force_cost(a: np.ndarray, b: np.ndarray, k: int) -> float:
    """Eq. (1)-(2) by explicit loops over every start and every allowed jump: O(n * m * n * k)."""
    m, n = len(a), len(b)
    dist = np.linalg.norm(a[:, None] - b[None], axis=2)
    best = np.inf
    for start in range(n):
        table = np.full((m, n + 1), np.inf)
        table[0, 0] = dist[0, start]
        for i in range(1, m):
            for j in range(n + 1):
                for jump in range(min(k, j) + 1):
                    table[i, j] = min(table[i, j], table[i - 1, j - jump] + dist[i, (start + j) % n])
        best = min(best, table[m - 1, max(0, n - k):].min())
    return best


def guitar_regions(shape, body, neck_width, neck_length, cx, cy, hole):
    """Label map: 0 body (two ellipses), 1 neck, 2 headstock, 3 sound hole; -1 background."""
    regions = np.full(shape, -1, np.int32)
    cv2.ellipse(regions, (cx, cy), (body, int(body * 1.2)), 0, 0, 360, 0, -1)
    cv2.ellipse(regions, (cx, cy - int(body * 1.3)), (int(body * 0.8), int(body * 0.7)), 0, 0, 360, 0, -1)
    top = cy - int(body * 1.8)
    regions[top - neck_length:top + 5, cx - neck_width:cx + neck_width + 1] = 1
    regions[top - neck_length - 40:top - neck_length, cx - neck_width - 8:cx + neck_width + 9] = 2
    cv2.circle(regions, (cx, cy - int(body * 0.9)), hole, 3, -1)
    return regions


INPUT_REGIONS = guitar_regions((512, 512), 80, 12, 150, 250, 380, 22)
TEMPLATE_REGIONS = guitar_regions((512, 512), 70, 9, 170, 258, 390, 18)


def test_trace_contour_orientation_and_start():
    mask = np.zeros((30, 40), bool)
    mask[5:15, 10:30] = True  # 10 rows x 20 cols
    contour = trace_contour(mask)
    assert len(contour) == 2 * (10 + 20) - 4  # one point per boundary pixel
    assert tuple(contour[0]) == (10, 5)  # top-most, then left-most
    x, y = contour[:, 0], contour[:, 1]
    assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0  # counter-clockwise on screen (y down)
    assert tuple(contour[1]) == (10, 6)  # so it leaves the top-left corner downwards


def test_trace_contour_keeps_the_largest_component():
    mask = np.zeros((50, 50), bool)
    mask[2:5, 2:5] = True
    mask[20:40, 10:45] = True
    contour = trace_contour(mask)
    assert contour[:, 1].min() == 20 and contour[:, 0].max() == 44
    with pytest.raises(InputError):
        trace_contour(np.zeros((10, 10), bool))


def test_contour_matched_to_itself_is_the_identity():
    contour = trace_contour(INPUT_REGIONS >= 0)
    shifted = np.roll(contour, 57, axis=0)  # same outline, starting elsewhere
    omega = match_contours(contour, shifted, k=default_k(512))
    assert np.array_equal(omega, (np.arange(len(contour)) + 57) % len(contour))


@pytest.mark.parametrize("k", [3, 20, 150])
def test_jump_bound_and_single_turn(k):
    a = trace_contour(INPUT_REGIONS >= 0)
    b = trace_contour(TEMPLATE_REGIONS >= 0)
    omega = match_contours(a, b, k)
    steps = cyclic_steps(omega, len(b))
    assert steps.max() <= k
    assert steps.sum() == len(b)  # monotone, goes round the template exactly once


def test_dynamic_programme_matches_brute_force():
    rng = np.random.default_rng(7)
    for _ in range(3):
        m, n, k = int(rng.integers(34, 44)), int(rng.integers(34, 44)), int(rng.integers(2, 6))
        t = np.sort(rng.uniform(0, 2 * np.pi, m))
        a = np.c_[20 + 10 * np.cos(t), 20 + 6 * np.sin(t)] + rng.normal(0, 1.5, (m, 2))
        b = rng.uniform(5, 35, (n, 2))
        omega = match_contours(a, b, k, starts=range(n))
        assert cyclic_steps(omega, n).max() <= k and cyclic_steps(omega, n).sum() == n
        assert match_cost(a, b, omega) == pytest.approx(brute_force_cost(a, b, k), rel=1e-9)


def test_default_starts_find_the_cyclic_optimum_on_aligned_outlines():
    a = trace_contour(INPUT_REGIONS >= 0)[::4]
    b = trace_contour(TEMPLATE_REGIONS >= 0)[::4]
    k = 10
    best = match_contours(a, b, k, starts=range(len(b)))
    default = match_contours(a, b, k)
    assert match_cost(a, b, default) <= match_cost(a, b, best) * 1.001


def test_too_small_k_is_an_input_error():
    a = trace_contour(INPUT_REGIONS == 3)
    b = trace_contour(TEMPLATE_REGIONS >= 0)
    with pytest.raises(InputError, match="too small"):
        match_contours(a, b, k=2)


def test_default_k_scales_with_resolution():
    assert default_k(350) == 128
    assert default_k(700) == 256
    assert default_k(175) == 64


def test_region_refinement_keeps_neck_on_neck():
    a = trace_contour(INPUT_REGIONS >= 0)
    b = trace_contour(TEMPLATE_REGIONS >= 0)
    omega = match_contours(a, b, default_k(512))
    refined = match_regions(INPUT_REGIONS, TEMPLATE_REGIONS, a, b, omega, K=32)

    def label_agreement(om):
        input_labels = INPUT_REGIONS[a[:, 1].astype(int), a[:, 0].astype(int)]
        template_labels = TEMPLATE_REGIONS[b[om, 1].astype(int), b[om, 0].astype(int)]
        return np.mean(input_labels == template_labels)

    assert refined.shape == omega.shape and refined.min() >= 0 and refined.max() < len(b)
    assert cyclic_steps(refined, len(b)).sum() == len(b)  # still monotone, one turn
    assert label_agreement(refined) > 0.98
    assert label_agreement(refined) > label_agreement(omega)


def test_region_refinement_without_common_regions_keeps_the_global_match():
    a = trace_contour(INPUT_REGIONS >= 0)
    b = trace_contour(TEMPLATE_REGIONS >= 0)
    omega = match_contours(a, b, default_k(512))
    relabelled = np.where(TEMPLATE_REGIONS >= 0, TEMPLATE_REGIONS + 10, -1)
    assert np.array_equal(match_regions(INPUT_REGIONS, relabelled, a, b, omega), omega)


def test_region_pivots_lie_on_inner_boundaries():
    inputs, templates = region_pivots(INPUT_REGIONS, TEMPLATE_REGIONS, K=32, max_pairs=120)
    assert inputs.shape == templates.shape and 20 <= len(inputs) <= 120
    for points, regions in ((inputs, INPUT_REGIONS), (templates, TEMPLATE_REGIONS)):
        rows, cols = points[:, 1].astype(int), points[:, 0].astype(int)
        neighbourhood = np.stack([regions[rows + dr, cols + dc] for dr in (-1, 0, 1) for dc in (-1, 0, 1)])
        assert (neighbourhood >= 0).all()  # never on the outer silhouette
        assert (neighbourhood != neighbourhood[4]).any(axis=0).all()  # always next to another region
    # a pivot on the input's sound hole is paired with a point on the template's sound hole
    on_hole = INPUT_REGIONS[inputs[:, 1].astype(int), inputs[:, 0].astype(int)] == 3
    assert on_hole.any()
    hole_centre = np.array([258, 390 - int(70 * 0.9)])
    assert np.all(np.abs(np.linalg.norm(templates[on_hole] - hole_centre, axis=1) - 18) < 2.5)


def test_region_maps_must_be_integer_labels():
    a = trace_contour(INPUT_REGIONS >= 0)
    with pytest.raises(InputError, match="region map"):
        match_regions(INPUT_REGIONS.astype(float), TEMPLATE_REGIONS, a, a, np.arange(len(a)))
