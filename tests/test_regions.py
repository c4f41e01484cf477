"""Region segmentation default: transferred template regions refined by colour and graph cuts."""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

from frontal3d.errors import InputError
from frontal3d.family import Family
from frontal3d.stages.regions import reconstruct_region_map, refine_regions, segment_regions


def _two_colour_object(shape: tuple[int, int] = (240, 320)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A noisy ellipse whose upper part is one colour and the lower part another; its true region map."""
    rng = np.random.default_rng(0)
    mask = np.zeros(shape, np.uint8)
    cv2.ellipse(mask, (shape[1] // 2, shape[0] // 2), (shape[1] // 3, shape[0] // 3 + 20), 0, 0, 360, 1, -1)
    mask = mask > 0
    truth = np.where(mask, 0, -1).astype(np.int32)
    rows = np.arange(shape[0])[:, None]
    disc = (rows - shape[0] // 2 - 25) ** 2 + (np.arange(shape[1])[None] - shape[1] // 2) ** 2 < 45**2
    truth[mask & disc] = 1
    image = np.where(truth[..., None] == 1, np.array([60, 40, 30]), np.array([200, 150, 90]))
    image = np.where(mask[..., None], image, 240)
    image = np.clip(image + rng.normal(0, 10, image.shape), 0, 255).astype(np.uint8)
    return image, mask, truth


def _accuracy(found: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> float:
    return float((found[mask] == truth[mask]).mean())


def test_refine_regions_moves_a_shifted_region_map_back_onto_the_colours():
    image, mask, truth = _two_colour_object()
    shifted = np.full_like(truth, -1)
    shifted[:, 8:] = truth[:, :-8]
    shifted = np.roll(shifted, 8, axis=0)
    shifted[mask & (shifted < 0)] = 0
    shifted[~mask] = -1
    assert _accuracy(shifted, truth, mask) < 0.95
    refined = refine_regions(image, mask, shifted, n_regions=2)
    assert refined.dtype == np.int32
    assert np.all(refined[~mask] == -1)
    assert _accuracy(refined, truth, mask) > 0.95


def test_refine_regions_runs_in_about_a_second_at_480x640():
    image, mask, truth = _two_colour_object((480, 640))
    prior = np.where(mask, np.roll(truth, 10, axis=1).clip(0), -1)
    start = time.perf_counter()
    refined = refine_regions(image, mask, prior, n_regions=2)
    assert time.perf_counter() - start < 3.0
    assert _accuracy(refined, truth, mask) > 0.95


def test_reconstruct_region_map_fills_a_hole_and_keeps_one_component_per_region():
    mask = np.zeros((100, 120), bool)
    mask[10:90, 10:110] = True
    regions = np.where(mask, 0, -1).astype(np.int32)
    regions[10:90, 60:110] = 1
    regions[20:30, 20:30] = 1  # a stray piece of region 1 inside region 0
    hole = np.zeros_like(mask)
    hole[40:60, 40:80] = True  # occluded: straddles the boundary between regions
    regions[hole] = -1
    rebuilt = reconstruct_region_map(regions, mask, hole)
    assert np.all(rebuilt[mask] >= 0) and np.all(rebuilt[~mask] == -1)
    assert np.all(rebuilt[20:30, 20:30] == 0)
    assert np.all(rebuilt[45:55, 40:55] == 0) and np.all(rebuilt[45:55, 65:80] == 1)
    for label in (0, 1):
        count, _ = cv2.connectedComponents((rebuilt == label).astype(np.uint8), connectivity=4)
        assert count == 2


def test_mismatched_region_map_is_an_input_error():
    with pytest.raises(InputError, match="region map"):
        refine_regions(np.zeros((20, 30, 3), np.uint8), np.ones((20, 30), bool), np.zeros((20, 31), np.int32), 2)


def test_segment_regions_without_weights_refines_the_transferred_template_regions():
    image, mask, truth = _two_colour_object()
    family = Family(name="toy", subtypes=("one",), canonical_view="front", regions={"one": ("top", "disc")}, real_size={"one": 1.0})
    shifted = np.where(mask, np.roll(truth, 6, axis=1), -1)
    shifted[mask & (shifted < 0)] = 0
    found = segment_regions(image, mask, shifted, family, "one", {"weights": {}})
    np.testing.assert_array_equal(found, refine_regions(image, mask, shifted, 2))
    assert _accuracy(found, truth, mask) > 0.97
