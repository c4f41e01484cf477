"""Occlusions by arms and hands: the silhouette is rebuilt behind them from the template, and the people detector."""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path

import cv2
import frontal3d
import numpy as np
import pytest
from frontal3d.occluders import detect_arms_and_hands
from frontal3d.stages.occlusion import rebuild_silhouette

SKIN = (224, 172, 135)
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
needs_mediapipe = pytest.mark.skipif(importlib.util.find_spec("mediapipe") is None, reason="mediapipe is not installed (scripts/setup.sh installs it)")


def _ellipse(shape: tuple[int, int], centre: tuple[int, int], axes: tuple[int, int], angle: float = 0.0) -> np.ndarray:
    mask = np.zeros(shape, np.uint8)
    cv2.ellipse(mask, centre, axes, angle, 0, 360, 1, -1)
    return mask > 0


def _arm(shape: tuple[int, int], start: tuple[int, int], end: tuple[int, int], width: int) -> np.ndarray:
    """An arm-shaped band from ``start`` to a round hand at ``end``."""
    mask = np.zeros(shape, np.uint8)
    cv2.line(mask, start, end, 1, width)
    cv2.circle(mask, end, int(width * 0.8), 1, -1)
    return mask > 0


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


@pytest.fixture
def occluded_ellipse():
    """A red ellipse with a skin-coloured arm across its edge; the template is a slightly different ellipse."""
    shape = (300, 400)
    truth = _ellipse(shape, (200, 150), (150, 100))
    template = _ellipse(shape, (204, 147), (141, 95), angle=4.0)
    arm = _arm(shape, (250, 299), (330, 60), 34)
    image = np.full(shape + (3,), 235, np.uint8)
    image[truth] = (180, 40, 40)
    image[arm] = SKIN
    return image, truth, template, arm


def test_an_arm_across_the_edge_is_rebuilt_from_the_template(occluded_ellipse):
    _, truth, template, arm = occluded_ellipse
    visible = truth & ~arm
    assert _iou(visible, truth) < 0.9

    rebuilt = rebuild_silhouette(visible, arm, template)

    assert _iou(rebuilt.mask, truth) > 0.97
    summary = rebuilt.summary()
    parts = summary["rebuilt_boundary_parts"]
    assert len(parts) == 2  # the arm enters and leaves the ellipse's outline
    assert all(part["occluded_length_px"] > 10 and part["rebuilt_length_px"] > 10 for part in parts)
    assert summary["restored_pixels"] > 0.8 * (truth & arm).sum()
    assert rebuilt.occluded[rebuilt.mask & arm].all()  # everything behind the arm gets inpainted
    assert not (rebuilt.occluded & ~rebuilt.mask).any()


def test_a_mask_that_includes_the_arm_still_loses_the_arm_outside_the_object(occluded_ellipse):
    _, truth, template, arm = occluded_ellipse
    rebuilt = rebuild_silhouette(truth | arm, arm, template)
    assert _iou(rebuilt.mask, truth) > 0.97


def test_a_hand_inside_the_object_is_filled(occluded_ellipse):
    _, truth, template, _ = occluded_ellipse
    hand = _ellipse(truth.shape, (180, 140), (30, 22))
    rebuilt = rebuild_silhouette(truth & ~hand, hand, template)
    assert _iou(rebuilt.mask, truth) > 0.99
    assert rebuilt.summary()["rebuilt_boundary_parts"] == []
    assert rebuilt.occluded[hand].all()


def test_without_occluders_the_silhouette_is_unchanged(occluded_ellipse):
    _, truth, template, arm = occluded_ellipse
    far_away = np.zeros_like(arm)
    far_away[:20, :20] = True
    for occluders in (np.zeros_like(arm), far_away):
        rebuilt = rebuild_silhouette(truth, occluders, template)
        assert np.array_equal(rebuilt.mask, truth)
        assert not rebuilt.occluded.any()
        assert rebuilt.summary() == {"occluded_fraction": 0.0, "restored_pixels": 0, "rebuilt_boundary_parts": []}


@needs_mediapipe
def test_the_detector_finds_nobody_on_an_image_without_people_quickly(occluded_ellipse):
    image = occluded_ellipse[0].copy()
    image[occluded_ellipse[1]] = (180, 40, 40)  # the object alone, no arm
    detect_arms_and_hands(image)  # the first call loads the models once per process
    start = time.perf_counter()
    found = detect_arms_and_hands(image)
    assert time.perf_counter() - start < 0.3
    assert found is None or not found.any()


def test_without_mediapipe_the_detector_finds_nothing_and_warns(monkeypatch, caplog):
    from frontal3d import occluders

    monkeypatch.setitem(sys.modules, "mediapipe.python.solutions", None)  # its import now raises ImportError
    occluders._load_models.cache_clear()
    try:
        with caplog.at_level("WARNING", logger="frontal3d"):
            assert occluders.detect_arms_and_hands(np.zeros((64, 64, 3), np.uint8)) is None
        assert "mediapipe is not installed" in caplog.text
    finally:
        occluders._load_models.cache_clear()


def test_the_pipeline_rebuilds_a_car_behind_a_painted_arm():
    """examples/sportscar.png with an arm painted across its roof and sill: the mesh stays closed."""
    image = cv2.cvtColor(cv2.imread(str(EXAMPLES / "sportscar.png"), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGRA2RGBA)
    height, width = image.shape[:2]
    arm = _arm((height, width), (int(0.45 * width), height - 1), (int(0.6 * width), int(0.25 * height)), int(0.05 * width))
    image[arm, :3] = SKIN
    object_mask = (image[..., 3] > 127) & ~arm

    result = frontal3d.reconstruct(image[..., :3], "car", mask=object_mask, occluder_mask=arm)

    occlusion = result.report["occlusion"]
    assert occlusion["occluded_fraction"] > 0
    assert occlusion["restored_pixels"] > 0
    assert len(occlusion["rebuilt_boundary_parts"]) >= 1
    assert result.mesh.is_watertight
    assert result.maps["occlusion_mask"].any()

