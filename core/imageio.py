"""Reading input images and masks, with errors that name the file and the cause."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from frontal3d.errors import InputError

#: EXIF Orientation (tag 274) -> how to turn the stored pixels into what a viewer shows.
_EXIF_TURNS = {
    2: lambda data: data[:, ::-1],
    3: lambda data: data[::-1, ::-1],
    4: lambda data: data[::-1],
    5: lambda data: data.swapaxes(0, 1),
    6: lambda data: np.rot90(data, -1),
    7: lambda data: np.rot90(data, 2).swapaxes(0, 1),
    8: lambda data: np.rot90(data, 1),
}


def read_image(path: Path) -> np.ndarray:
    """Read an image as RGB or RGBA uint8 (alpha kept: it may be the object's mask)."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"cannot read image {path}: it is a folder (give the image files, e.g. {path}/*.jpg)")
    if not path.is_file():
        raise InputError(f"cannot read image {path}: no such file")
    return as_rgb(data_from_cv2(_decoded(path, "image")), str(path))


def _decoded(path: Path, what: str) -> np.ndarray:
    """OpenCV's pixels of an image file (BGR(A), 8 or 16 bits), turned as image viewers show them.

    Phones store a portrait photo sideways with an EXIF Orientation tag; OpenCV ignores the
    tag when it keeps the alpha channel (IMREAD_UNCHANGED), so without the turn a guitar held
    upright arrived lying down, and a mask painted over the photo as shown did not fit it.
    A JPEG cut short (an interrupted copy or download) is an error: OpenCV decodes it with its
    missing lower part grey and says so only on stderr, and the object's lower part was lost.
    """
    orientation, cut_short = _pil_look(path)
    if cut_short:
        raise InputError(f"cannot read {what} {path}: the file is cut short (its lower part is missing)")
    data = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if data is None or data.size == 0:
        cause = "the file is cut short" if _pil_look(path, decode_all=True)[1] else "not an image or unsupported format"
        raise InputError(f"cannot read {what} {path}: {cause}")
    turn = _EXIF_TURNS.get(orientation)
    return np.ascontiguousarray(turn(data)) if turn else data


def _pil_look(path: Path, decode_all: bool = False) -> tuple[int, bool]:
    """(EXIF orientation, whether the image data ends early) as PIL reads ``path``: (1, False) when
    PIL cannot tell (a format only OpenCV reads, over PIL's size limit, corrupt EXIF).

    JPEGs are decoded at an eighth of their size (``draft``), which still reads all of their
    data: about 40 ms for a 12-megapixel photo. Other formats only with ``decode_all``: OpenCV
    fails on those itself when they are cut short, and then only the cause is wanted.
    """
    orientation, cut_short = 1, False
    # PIL warns of a corrupt file on stderr; the one-line error says what matters.
    with warnings.catch_warnings(action="ignore"):
        try:
            with Image.open(path) as image:
                try:
                    orientation = image.getexif().get(274, 1)
                except (OSError, ValueError):
                    pass
                if image.format == "JPEG":
                    image.draft(image.mode, (max(1, image.width // 8), max(1, image.height // 8)))
                elif not decode_all:
                    return orientation, False
                image.load()
        except (OSError, SyntaxError) as error:
            cut_short = "truncated" in str(error)
        except (ValueError, Image.DecompressionBombError):
            pass
    return orientation, cut_short


def data_from_cv2(data: np.ndarray) -> np.ndarray:
    """OpenCV's BGR(A) -> RGB(A)."""
    if data.ndim == 3 and data.shape[2] == 3:
        return cv2.cvtColor(data, cv2.COLOR_BGR2RGB)
    if data.ndim == 3 and data.shape[2] == 4:
        return cv2.cvtColor(data, cv2.COLOR_BGRA2RGBA)
    return data


def as_rgb(image: np.ndarray, name: str = "image") -> np.ndarray:
    """Validate an in-memory image and give it 3 or 4 uint8 channels."""
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise InputError(f"{name}: expected an H x W x 3 or 4 image, got shape {image.shape}")
    if image.shape[0] < 16 or image.shape[1] < 16:
        raise InputError(f"{name}: image is too small ({image.shape[1]}x{image.shape[0]} pixels)")
    if image.dtype != np.uint8:
        if image.dtype == np.uint16:  # 16-bit photos (PNG, TIFF) span 0-65535
            image = image / 257.0
        elif np.issubdtype(image.dtype, np.floating) and image.max() <= 1.0:
            image = image * 255.0
        image = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    if int(image[..., :3].max()) == int(image[..., :3].min()) and (image.shape[2] == 3 or image[..., 3].min() == image[..., 3].max()):
        raise InputError(f"{name}: image is empty (every pixel has the same value)")
    return image


def read_mask(path: Path, shape: tuple[int, int]) -> np.ndarray:
    """Read a user's mask (object pixels as :func:`mask_from_array` reads them) and fit it to an image of ``shape``.

    A mask of another size is resized only when its aspect ratio matches the image's
    (a different aspect ratio means it belongs to another image).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"cannot read mask {path}: no such file")
    data = _single_channel(_decoded(path, "mask"))
    h, w = shape
    if data.shape != (h, w):
        if abs(data.shape[1] / data.shape[0] - w / h) > 0.01:
            raise InputError(f"mask {path} is {data.shape[1]}x{data.shape[0]} but the image is {w}x{h}")
        data = cv2.resize(data, (w, h), interpolation=cv2.INTER_NEAREST)
    mask = mask_from_array(data)
    if not mask.any():
        raise InputError(f"mask {path} is empty")
    return mask


def mask_from_array(data: np.ndarray) -> np.ndarray:
    """A mask's pixels as object / not object: past half the mask's range, so a soft matte's faint
    halo stays out (0-1 masks: above 0.5; others, e.g. 0-255: above half their largest value).
    A 4-channel mask is read by its alpha, a 3-channel one by its brightest channel."""
    data = _single_channel(np.asarray(data))
    if data.dtype == bool:
        return data
    peak = float(data.max()) if data.size else 0.0
    return data > (peak / 2 if peak > 1 else 0.5)


def _single_channel(data: np.ndarray) -> np.ndarray:
    """A mask stored with channels: its alpha when it has four, else its brightest channel."""
    if data.ndim != 3:
        return data
    return data[..., 3] if data.shape[2] == 4 else data.max(axis=2)
