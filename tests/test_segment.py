"""Object segmentation defaults: user masks, alpha channels and the GrabCut fallback."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from frontal3d.errors import InputError
from frontal3d.imageio import read_mask
from frontal3d.stages.segment import grabcut_segment, mask_from_alpha, split_objects


def _ellipse_mask(shape: tuple[int, int]) -> np.ndarray:
    mask = np.zeros(shape, np.uint8)
    h, w = shape
    cv2.ellipse(mask, (w // 2 + 10, h // 2 - 5), (w // 5, h // 3), 20, 0, 360, 1, -1)
    return mask > 0


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def _composite(background: np.ndarray, mask: np.ndarray, colour: tuple[int, int, int], rng: np.random.Generator) -> np.ndarray:
    """An object with a little shading and sensor noise over ``background``."""
    h, w = mask.shape
    shading = np.linspace(0.85, 1.1, w)[None, :, None]
    obj = np.clip(np.array(colour, np.float64)[None, None] * shading, 0, 255)
    image = np.where(mask[..., None], obj, background)
    return np.clip(image + rng.normal(0, 6, image.shape), 0, 255).astype(np.uint8)


def test_grabcut_finds_an_ellipse_on_a_noisy_plain_background():
    rng = np.random.default_rng(1)
    shape = (480, 640)
    truth = _ellipse_mask(shape)
    background = np.full(shape + (3,), (225, 228, 232), np.float64)
    found = grabcut_segment(_composite(background, truth, (170, 40, 35), rng))
    assert found is not None and found.shape == shape
    assert _iou(found, truth) > 0.9


def test_grabcut_finds_an_ellipse_on_a_mildly_cluttered_background():
    rng = np.random.default_rng(2)
    shape = (480, 640)
    truth = _ellipse_mask(shape)
    background = np.empty(shape + (3,))
    background[:] = np.linspace(150, 205, shape[1])[None, :, None] * np.array([0.9, 1.0, 1.05])
    for _ in range(12):
        blob = np.zeros(shape, np.float32)
        centre = (int(rng.integers(0, shape[1])), int(rng.integers(0, shape[0])))
        cv2.circle(blob, centre, int(rng.integers(25, 70)), 1.0, -1)
        blob = cv2.GaussianBlur(blob, (0, 0), 15)[..., None]
        background = background * (1 - blob) + blob * rng.uniform(110, 230, 3)
    found = grabcut_segment(_composite(background, truth, (30, 70, 160), rng))
    assert found is not None
    assert _iou(found, truth) > 0.85


def test_grabcut_returns_none_for_an_image_without_an_object():
    rng = np.random.default_rng(3)
    plain = np.clip(rng.normal(128, 5, (200, 300, 3)), 0, 255).astype(np.uint8)
    assert grabcut_segment(plain) is None


def test_alpha_channel_is_the_mask_unless_fully_opaque():
    rgba = np.zeros((40, 50, 4), np.uint8)
    rgba[10:30, 5:20, 3] = 255
    mask = mask_from_alpha(rgba)
    assert mask is not None and mask.sum() == 20 * 15 and mask[15, 10] and not mask[0, 0]
    rgba[..., 3] = 255
    assert mask_from_alpha(rgba) is None
    assert mask_from_alpha(rgba[..., :3]) is None


def test_user_mask_is_resized_only_when_the_aspect_ratio_matches(tmp_path):
    mask = np.zeros((50, 100), np.uint8)
    mask[10:40, 20:60] = 255
    path = tmp_path / "mask.png"
    cv2.imwrite(str(path), mask)
    same = read_mask(path, (50, 100))
    assert same.dtype == bool and same.sum() == 30 * 40
    doubled = read_mask(path, (100, 200))
    assert doubled.shape == (100, 200) and doubled.sum() == 60 * 80
    with pytest.raises(InputError, match=r"100x50.*120x50"):
        read_mask(path, (50, 120))


def test_split_objects_orders_by_size_and_drops_specks():
    mask = np.zeros((100, 100), bool)
    mask[5:45, 5:45] = True
    mask[60:90, 60:90] = True
    mask[95:97, 2:4] = True
    objects = split_objects(mask)
    assert [int(o.sum()) for o in objects] == [1600, 900]
