"""Mirror completion of a hidden outline (issue #7): the object's own other half, where it is seen.

The paper rebuilds each hidden stretch of the outline from the aligned template. That
guess is only as good as the template's likeness: a star-shaped or pointed guitar body,
for which no template exists, gets a round bout where a point should be. Most objects
a family covers are mirror-symmetric in their canonical view (a guitar's face about the
neck, a plane's planform about the fuselage), so where the mirror image of a hidden
pixel is seen, the object itself says what is there.

The mirror line is searched near the aligned template's axis. Agreement is counted only
where a pixel and its mirror image are both seen, for the object's mirror image and for
the template on the same pixels; the mirror replaces the template only where it explains
what is seen better than the template does, and only where the mirror image is seen.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from scipy.ndimage import binary_fill_holes

from frontal3d.masks import mask_extent
from frontal3d.stages.mirror_symmetry import upright_turn

#: Tilts (degrees) of the mirror line searched about the aligned template's axis.
TILTS = tuple(range(-8, 9))
#: How far (share of the object's size) the mirror line may sit from the template's axis.
OFFSET_LIMIT = 0.15
#: The object's mirror image must agree with the object on the pixels seen on both sides
#: at least this well (IoU) before it may stand in for the template (and better than the
#: template does): a bass's offset horns reach 0.73 against its template's 0.60.
MIN_AGREEMENT = 0.7
#: Pixels seen on both sides must hold at least this share of the seen object: a mirror
#: judged on a sliver is not evidence. A person over one side of a body leaves its neck
#: and the other side: about a quarter of the seen object.
MIN_SEEN_BOTH = 0.2
#: Longest side, in pixels, of the grid the line is searched on (a photo's full resolution
#: is shrunk to it; the working grid is smaller already).
SEARCH_SIZE = 400


@dataclass(frozen=True)
class MirrorLine:
    """A mirror line in image pixels, the object's agreement with its mirror image and the template's."""

    matrix: np.ndarray  # 2x3 affine reflection (an involution: it is its own inverse)
    agreement: float
    template_agreement: float
    seen_both: float  # share of the seen object whose mirror image is seen too

    @property
    def usable(self) -> bool:
        """The object is symmetric on what is seen, and more so than the template is like it."""
        return self.seen_both >= MIN_SEEN_BOTH and self.agreement >= MIN_AGREEMENT and self.agreement > self.template_agreement

    def to_dict(self) -> dict[str, Any]:
        return {
            "agreement": round(self.agreement, 4),
            "template_agreement": round(self.template_agreement, 4),
            "seen_both": round(self.seen_both, 4),
        }


def find_mirror_line(visible: np.ndarray, unknown: np.ndarray, template_mask: np.ndarray, axis: float) -> MirrorLine | None:
    """The line, near the placed template's axis, about which the seen object best matches its mirror image.

    ``visible`` is the seen object, ``unknown`` the pixels whose content is not seen (near
    occluders; off the image counts as unknown too), ``template_mask`` the placed template,
    ``axis`` its mirror line's direction (radians from image-up, counter-clockwise on screen).
    For each tilt the masks are turned so the line is vertical; every row's overlap with its
    own reflection about every column is a convolution, done by FFT for all columns at once:
    with V the seen object and K the seen pixels, the IoU on pixels seen on both sides is
    (V * V) / (2 (V * K) - V * V).
    """
    visible = np.asarray(visible, dtype=bool)
    if not visible.any() or not template_mask.any():
        return None
    if max(visible.shape) > SEARCH_SIZE:
        return _found_on_smaller_grid(visible, unknown, template_mask, axis)
    rows, cols = np.nonzero(template_mask)
    centre = (float(cols.mean()), float(rows.mean()))
    size = mask_extent(template_mask)
    side = int(np.ceil(np.hypot(*visible.shape))) + 2
    seen = ~np.asarray(unknown, dtype=bool)
    known, seen_object = seen.astype(np.float32), (visible & seen).astype(np.float32)
    lo = int(np.floor(2 * (side / 2 - OFFSET_LIMIT * size)))
    hi = int(np.ceil(2 * (side / 2 + OFFSET_LIMIT * size)))
    doubled = np.arange(max(lo, 0), min(hi, 2 * side - 1) + 1)
    best: tuple[float, np.ndarray] | None = None
    for tilt in TILTS:
        turn = upright_turn(centre, axis + np.deg2rad(tilt), side)
        v = cv2.warpAffine(seen_object, turn[:2], (side, side), flags=cv2.INTER_LINEAR, borderValue=0.0)
        k = cv2.warpAffine(known, turn[:2], (side, side), flags=cv2.INTER_LINEAR, borderValue=0.0)
        fv, fk = np.fft.rfft(v, n=2 * side, axis=1), np.fft.rfft(k, n=2 * side, axis=1)
        inter = np.fft.irfft(fv * fv, n=2 * side, axis=1).sum(axis=0)[doubled]
        seen_side = np.fft.irfft(fv * fk, n=2 * side, axis=1).sum(axis=0)[doubled]
        iou = inter / np.maximum(2 * seen_side - inter, 1e-9)
        index = int(np.argmax(iou))
        if best is None or iou[index] > best[0]:
            flip = np.array([[-1.0, 0.0, float(doubled[index])], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
            best = (float(iou[index]), (np.linalg.inv(turn) @ flip @ turn)[:2])
    agreement, matrix = best
    seen_both = seen & reflected(seen, matrix)
    template = np.asarray(template_mask, dtype=bool)
    template_agreement = np.count_nonzero(template & visible & seen_both) / max(np.count_nonzero((template | visible) & seen_both), 1)
    share = np.count_nonzero(visible & seen_both) / max(np.count_nonzero(visible), 1)
    return MirrorLine(matrix, agreement, float(template_agreement), float(share))


def mirror_filled(rebuilt: np.ndarray, visible: np.ndarray, unknown: np.ndarray, occluders: np.ndarray, line: MirrorLine) -> np.ndarray:
    """The rebuilt mask with the template's guess replaced by the object's mirror image wherever that is seen.

    The template's restored pixels stay where the mirror image is hidden too, and beyond the
    seen object's span along the line, where the mirror cannot say: a neck above a body whose
    top a person hides has its mirror image on itself only if the line runs exactly along it
    (a degree off, it swings off the neck onto seen background). The mirror image adds
    pixels only under the occluders (one pixel of slack), never on what the image shows as
    background.
    """
    visible = np.asarray(visible, dtype=bool)
    mirror_unknown = reflected(unknown, line.matrix, outside=True)
    restored_by_template = np.asarray(rebuilt, dtype=bool) & ~visible & (mirror_unknown | ~_within_seen_span(visible, line.matrix))
    under_occluders = cv2.dilate(np.asarray(occluders, dtype=np.uint8), np.ones((3, 3), np.uint8)) > 0
    mirrored = reflected(visible, line.matrix) & ~mirror_unknown & under_occluders
    joined = visible | restored_by_template | mirrored
    joined = cv2.morphologyEx(joined.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)) > 0
    _count, pieces = cv2.connectedComponents(joined.astype(np.uint8))
    keep = np.unique(pieces[visible & (pieces > 0)])
    return binary_fill_holes(np.isin(pieces, keep) | visible)


def _within_seen_span(visible: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Pixels whose position along the mirror line lies within the seen object's."""
    linear = np.asarray(matrix)[:, :2]
    values, vectors = np.linalg.eigh((linear + linear.T) / 2)
    direction = vectors[:, int(np.argmax(values))]  # a reflection keeps its line's direction (eigenvalue +1)
    rows, cols = np.indices(visible.shape)
    along = cols * direction[0] + rows * direction[1]
    seen = along[visible]
    return (along >= seen.min()) & (along <= seen.max())


def _found_on_smaller_grid(visible: np.ndarray, unknown: np.ndarray, template_mask: np.ndarray, axis: float) -> MirrorLine | None:
    """:func:`find_mirror_line` on the masks shrunk to SEARCH_SIZE, its reflection carried back to full-size pixels."""
    factor = SEARCH_SIZE / max(visible.shape)
    size = (max(1, round(visible.shape[1] * factor)), max(1, round(visible.shape[0] * factor)))
    def shrunk(mask: np.ndarray) -> np.ndarray:
        return cv2.resize(np.asarray(mask, dtype=np.float32), size, interpolation=cv2.INTER_AREA) >= 0.5
    line = find_mirror_line(shrunk(visible), shrunk(unknown), shrunk(template_mask), axis)
    if line is None:
        return None
    # cv2.resize's pixel centres: x_small = (x + 0.5) * f - 0.5, per axis.
    fx, fy = size[0] / visible.shape[1], size[1] / visible.shape[0]
    to_small = np.array([[fx, 0.0, 0.5 * fx - 0.5], [0.0, fy, 0.5 * fy - 0.5], [0.0, 0.0, 1.0]])
    matrix = np.linalg.inv(to_small) @ np.vstack([line.matrix, [0.0, 0.0, 1.0]]) @ to_small
    return MirrorLine(matrix[:2], line.agreement, line.template_agreement, line.seen_both)


def reflected(mask: np.ndarray, matrix: np.ndarray, *, outside: bool = False) -> np.ndarray:
    """The mask seen in the mirror ``matrix`` (a :class:`MirrorLine`'s): pixel p takes the value at
    its mirror image, ``outside`` where that lies beyond the image."""
    height, width = mask.shape
    return cv2.warpAffine(np.asarray(mask, dtype=np.uint8), matrix, (width, height), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=int(outside)) > 0
