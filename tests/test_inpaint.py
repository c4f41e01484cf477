"""Per-region inpainting: occluded pixels are refilled from their own region only."""

import time

import numpy as np
import pytest
from scipy import ndimage

from frontal3d.errors import InputError
from frontal3d.stages.inpaint import inpaint_regions, largest_square, scaled_patch_range

OCCLUDER = np.array([0, 255, 0], np.uint8)


def _two_region_scene(seed=0, with_arm=True):
    """A 200 x 200 photo: a wide noisy-red region 0, a 10 px wide noisy-blue strip (region 1),
    and a green 'arm' covering parts of both."""
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[:200, :200]
    region_map = np.full((200, 200), -1)
    region_map[20:180, 20:150] = 0
    region_map[20:180, 150:160] = 1
    image = np.full((200, 200, 3), 40, np.uint8)
    red = np.array([200, 40, 30]) + rng.integers(-20, 21, (200, 200, 1))
    blue = np.array([30, 50, 190]) + rng.integers(-20, 21, (200, 200, 1))
    image[region_map == 0] = red[region_map == 0]
    image[region_map == 1] = blue[region_map == 1]
    arm = (np.abs(rows - 100) < 15) & (cols > 90) & (cols < 175)
    if with_arm:
        image[arm] = OCCLUDER
    return image, region_map, arm


def _colour_box(image, pixels):
    colours = image[pixels].astype(int)
    return colours.min(axis=0), colours.max(axis=0)


def test_each_region_is_filled_only_with_its_own_colours():
    image, region_map, arm = _two_region_scene()
    out = inpaint_regions(image, region_map, arm)
    for label in (0, 1):
        region = region_map == label
        low, high = _colour_box(image, region & ~arm)
        filled = out[region & arm].astype(int)
        assert np.all((filled >= low) & (filled <= high)), f"region {label} got foreign colours"
    assert not np.any(np.all(out[(region_map >= 0) & arm] == OCCLUDER, axis=1))


def test_pixels_outside_the_regions_and_far_from_the_hole_are_unchanged():
    image, region_map, arm = _two_region_scene()
    out = inpaint_regions(image, region_map, arm)
    np.testing.assert_array_equal(out[region_map == -1], image[region_map == -1])
    far = ~ndimage.binary_dilation(arm, iterations=12)
    np.testing.assert_array_equal(out[far], image[far])


def test_quilting_keeps_the_texture_instead_of_smearing_it():
    rng = np.random.default_rng(3)
    rows, cols = np.mgrid[:300, :300]
    stripes = (128 + 80 * np.sign(np.sin((cols + 0.3 * rows) / 4.0)) + rng.normal(0, 6, (300, 300))).clip(0, 255)
    image = np.repeat(stripes[..., None], 3, axis=2).astype(np.uint8)
    region_map = np.zeros((300, 300), int)
    hole = (rows - 150) ** 2 + (cols - 150) ** 2 < 60**2
    out = inpaint_regions(image, region_map, hole)
    filled, visible = out[hole][:, 0].astype(float), image[~hole][:, 0].astype(float)
    assert filled.std() > 0.9 * visible.std()
    assert abs(filled.mean() - visible.mean()) < 8


def test_a_region_with_no_visible_pixel_is_still_filled():
    image, region_map, _ = _two_region_scene(with_arm=False)
    hidden = region_map == 1
    image[hidden] = OCCLUDER
    out = inpaint_regions(image, region_map, hidden)
    assert not np.any(np.all(out[hidden] == OCCLUDER, axis=1))


def test_a_region_with_no_visible_pixel_takes_no_colour_from_beyond_the_object():
    """The arm reaches past the object's edge (columns 160-175): a hidden region next to it is
    filled from the object around it, not with the arm's colour."""
    image, region_map, arm = _two_region_scene()
    hidden = (region_map == 1) | (arm & (region_map >= 0))
    out = inpaint_regions(image, region_map, hidden)
    filled = out[region_map == 1].astype(int)
    assert filled[:, 1].max() < 128  # the object's colours have little green; the arm is pure green
    np.testing.assert_array_equal(out[region_map == -1], image[region_map == -1])


def test_same_seed_gives_same_result():
    image, region_map, arm = _two_region_scene()
    np.testing.assert_array_equal(inpaint_regions(image, region_map, arm, seed=5),
                                  inpaint_regions(image, region_map, arm, seed=5))


def test_largest_square_lies_inside_the_mask():
    mask = np.zeros((100, 120), bool)
    mask[10:50, 30:100] = True
    mask[60:95, 5:20] = True
    top, left, side = largest_square(mask)
    assert side >= 39
    assert mask[top:top + side, left:left + side].all()
    assert largest_square(mask, max_side=20)[2] == 20
    assert largest_square(np.zeros((5, 5), bool)) is None


def test_patch_sizes_shrink_with_small_images():
    assert scaled_patch_range((2000, 3000, 3), 60, 100) == (60, 100)
    assert scaled_patch_range((500, 800, 3), 60, 100) == (30, 50)


def test_one_megapixel_image_with_a_ten_percent_hole_finishes():
    rng = np.random.default_rng(0)
    rows, cols = np.mgrid[:1000, :1000]
    region_map = np.where(cols < 700, 0, np.where(cols < 730, 1, 2))
    base = np.array([[180, 120, 60], [40, 30, 20], [90, 90, 160]])[region_map]
    image = (base + 25 * np.sin(cols / 6.0 + rows / 40.0)[..., None] + rng.normal(0, 4, base.shape)).clip(0, 255)
    image = image.astype(np.uint8)
    hole = (rows - 500) ** 2 + (cols - 650) ** 2 < 178**2
    assert 0.09 < hole.mean() < 0.11
    start = time.perf_counter()
    out = inpaint_regions(image, region_map, hole)
    print(f"inpaint 1000x1000, {hole.mean():.1%} hole: {time.perf_counter() - start:.2f} s")
    assert out.shape == image.shape and out.dtype == np.uint8


def test_mismatched_inputs_are_rejected():
    image, region_map, arm = _two_region_scene()
    with pytest.raises(InputError, match="region map"):
        inpaint_regions(image, region_map[:-1], arm)
    with pytest.raises(InputError, match="uint8"):
        inpaint_regions(image.astype(float), region_map, arm)
