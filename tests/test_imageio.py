"""Reading photos: what a viewer shows is what the pipeline gets."""

import numpy as np
import pytest
from PIL import Image, ImageOps

from frontal3d.errors import InputError
from frontal3d.imageio import as_rgb, mask_from_array, read_image, read_mask

EXIF_ORIENTATION = 274


def _save_with_orientation(path, pixels: np.ndarray, orientation: int, **options) -> None:
    image = Image.fromarray(pixels)
    exif = image.getexif()
    exif[EXIF_ORIENTATION] = orientation
    image.save(path, exif=exif, **options)


@pytest.mark.parametrize("orientation", range(1, 9))
def test_every_exif_orientation_is_shown_upright_with_its_alpha(tmp_path, orientation):
    rng = np.random.default_rng(orientation)
    stored = rng.integers(0, 256, (24, 40, 4), dtype=np.uint8)  # lopsided: any wrong turn shows
    path = tmp_path / "photo.png"
    _save_with_orientation(path, stored, orientation)
    with Image.open(path) as image:
        shown = np.asarray(ImageOps.exif_transpose(image))
    np.testing.assert_array_equal(read_image(path), shown)


def test_a_portrait_phone_photo_and_its_mask_come_upright(tmp_path):
    """Phones store portrait photos sideways (Orientation 6: turn 90 degrees clockwise to show)."""
    upright = np.zeros((80, 48, 3), np.uint8)
    upright[10:70, 14:34] = (200, 120, 40)  # a tall object, as the user sees it
    photo = tmp_path / "IMG_0001.jpg"
    _save_with_orientation(photo, np.rot90(upright, 1), 6, quality=95)
    image = read_image(photo)
    assert image.shape == (80, 48, 3)
    seen = image[..., 0] > 100
    expected = upright[..., 0] > 100
    assert (seen & expected).sum() / (seen | expected).sum() > 0.95  # JPEG's loss only
    painted = tmp_path / "mask.png"
    Image.fromarray((upright.any(axis=2) * 255).astype(np.uint8)).save(painted)
    mask = read_mask(painted, image.shape[:2])
    assert mask[40, 24] and not mask[5, 5]


def _cut_in_half(path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


@pytest.mark.parametrize("suffix", [".jpg", ".png"])
def test_a_photo_cut_short_is_a_one_line_error_not_a_half_grey_photo(tmp_path, suffix):
    """OpenCV decodes a JPEG cut short with its lower half grey, and says so only on stderr."""
    rng = np.random.default_rng(3)
    pixels = rng.integers(0, 256, (96, 128, 3), dtype=np.uint8)
    photo = tmp_path / f"photo{suffix}"
    Image.fromarray(pixels).save(photo)
    assert read_image(photo).shape == (96, 128, 3)  # whole, it reads
    _cut_in_half(photo)
    with pytest.raises(InputError, match=f"cannot read image {photo}: the file is cut short"):
        read_image(photo)


def test_a_mask_cut_short_is_a_one_line_error(tmp_path):
    mask = np.zeros((96, 128), np.uint8)
    mask[20:70, 30:100] = 255
    path = tmp_path / "mask.jpg"
    Image.fromarray(mask).save(path)
    assert read_mask(path, (96, 128)).any()
    _cut_in_half(path)
    with pytest.raises(InputError, match="cannot read mask .*: the file is cut short"):
        read_mask(path, (96, 128))


def test_arrays_of_any_common_layout_come_in_as_the_same_8_bit_photo(tmp_path):
    """What the Python API is handed: 16-bit, float 0-1, single-channel (H, W, 1) arrays."""
    rng = np.random.default_rng(5)
    photo = rng.integers(0, 256, (40, 56, 3), dtype=np.uint8)
    np.testing.assert_array_equal(as_rgb(photo.astype(np.uint16) * 257), photo)
    np.testing.assert_array_equal(as_rgb(photo.astype(np.float32) / 255.0), photo)
    grey = photo[..., 0]
    np.testing.assert_array_equal(as_rgb(grey[..., None]), np.repeat(grey[..., None], 3, axis=2))
    path = tmp_path / "photo16.png"
    Image.fromarray(photo[..., 0].astype(np.uint16) * 257).save(path)  # a 16-bit grey PNG
    np.testing.assert_array_equal(read_image(path), np.repeat(grey[..., None], 3, axis=2))


def test_a_soft_matte_is_read_the_same_as_array_or_file_whatever_its_range(tmp_path):
    """A matte's faint halo is not object, whether the matte comes as 0-255, 0-1 or a PNG."""
    yy, xx = np.mgrid[:60, :80]
    distance = np.hypot(yy - 30, xx - 40)
    matte = np.clip(1.0 - (distance - 15) / 10, 0, 1)  # solid to r = 15, fading to 0 at r = 25
    core = distance < 20  # where the matte is above one half
    clear = np.abs(matte - 0.5) > 0.01  # 8-bit rounding may go either way right at one half
    as_8_bit = np.rint(matte * 255).astype(np.uint8)
    path = tmp_path / "matte.png"
    Image.fromarray(as_8_bit).save(path)
    readings = [mask_from_array(matte), mask_from_array(as_8_bit), mask_from_array(np.dstack([as_8_bit] * 4)),
                read_mask(path, (60, 80)), mask_from_array(core)]
    for reading in readings:
        np.testing.assert_array_equal(reading[clear], core[clear])
