"""Mirror repair of a segmented mask (issue #6): the object's own symmetry corrects its mask.

A plane seen from above is mirror-symmetric about its fuselage. Over a busy background the
segmenter can take in a blob that touches a wing (a patch of the object's own grey, or a
colour the network lent its halo to), or lose a wing that is close to the background's
colour. Either way the mask loses its symmetry in one chunky piece, and the piece's mirror
image says which error it is:

* a piece of the mask whose mirror image looks like the object (nearer the colours of the
  mask's symmetric part than of the background around it), and either looks like the piece
  itself or lies against the mirror line (half a fuselage), is half of a pair the segmenter
  broke: its mirror image is added;
* a piece whose mirror image looks like background is cut, if it meets the rest of the
  object along an image edge (a blob over the background meets the object along the
  object's outline) or does not meet it at all, and is not itself object-coloured (clearly
  nearer the object's colours than the background's: :data:`OBJECT_NEARER`) unless the
  learned segmenter doubts it and its mirror image is clearly background.

The line is found on the outline (:func:`frontal3d.stages.mirror_symmetry.fit_mirror` with
``outline=True``) over every direction: a blob adds area on one side, which pulls an area-
based line towards it, but the object's outline still matches its mirror image. Thin
asymmetric slivers (a few degrees of roll, a fin seen slightly from the side) are left
alone: only pieces that hold a disc of :data:`PIECE_RADIUS` count. Families switch it on
with the ``mirror_repair`` setting (airplanes, guitars). A guitar's own parts break its
symmetry (a bass's long horn, a single cutaway), so guitars turn off the cut of doubted
object-coloured pieces (``mirror_repair_cuts_own_colour``: the pipeline then passes no
``probability``) and keep only the cut of pieces in a third colour.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from frontal3d.masks import disc, mask_extent
from frontal3d.stages.mirror_symmetry import OBJECT_BENDS, fit_mirror
from frontal3d.stages.segment import distance_to_colours

#: Longest side (pixels) of the image the repair works on; larger photos are shrunk to it and
#: the pieces it cuts or adds carried back to full size.
WORK_SIZE = 512
#: Directions (degrees from image-up) of the coarse line search, then the refinement around the best.
COARSE_TILTS = tuple(range(-90, 90, 2))
FINE_TILTS = (-1.5, -1.0, -0.5, 0.5, 1.0, 1.5)
#: Side of the refinement's grid (the coarse search runs on mirror_symmetry.GRID).
FINE_GRID = 256
#: Below this outline agreement the line is not trusted (on the shared planes' composites the
#: lines that ran across the plane read 0.29-0.32; right lines with a blob stuck on 0.35 and up).
MIN_OUTLINE_AGREEMENT = 0.33
#: A piece of the mask without a mirror image counts only if it holds a disc of this radius
#: (share of the object's longest side).
PIECE_RADIUS = 0.02
#: A piece that comes within this many pixels of the line is half of something on the line.
ON_LINE = 2.5
#: A piece whose colours differ from its mirror image's by less than this (CIELAB, median) is
#: the same stuff on both sides.
SAME_COLOUR = 12.0
#: A piece is cut only if the image's gradient where it meets the rest of the object is at least
#: this many times the gradient inside the object's symmetric part: an outline lies there.
EDGE_RATIO = 3.0
#: How much nearer (CIELAB) a piece's mirror image must be to the object's colours than to the
#: background's before it is added, and to the background's before an object-coloured piece is cut.
CLEAR_GAP = 3.0
#: A piece is object-coloured when its colours lie nearer the object's than this share of their
#: distance to the background's: a blob of a third colour, about as far from both, is not.
OBJECT_NEARER = 0.75
#: Fewest pixels whose colours match their mirror partners' before the object's colours are read there only.
MIN_PAIRED_PIXELS = 50
#: A piece this near the object's colours (CIELAB, median) is object-coloured whatever lies
#: around the mask: the ring read as background may hold a part of the object the mask lost.
OWN_COLOUR = 3.0
#: An object-coloured piece may be a part of the object that a turn moved off its mirror image
#: (a rolled plane's fin or engine): it is cut only where the learned segmenter's mean p(object)
#: is below this too.
DOUBTED_P = 0.5


def mirror_repaired(image: np.ndarray, mask: np.ndarray, probability: np.ndarray | None = None,
                    paired_colours: bool = False) -> tuple[np.ndarray, dict[str, Any]]:
    """The mask with its asymmetric pieces cut or completed (see the module docstring), and what
    was done, for report.json (pixels cut and added at full size, and the line's agreement).

    ``probability`` is the learned segmenter's p(object) for the image, when one is configured:
    an object-coloured piece is cut only where the network, too, doubts it. With ``paired_colours``
    the object's colours are read only where both sides of the line look alike (:func:`_object_samples`)."""
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return mask, {}
    factor = min(1.0, WORK_SIZE / max(mask.shape))
    if factor < 1.0:
        size = (max(1, round(mask.shape[1] * factor)), max(1, round(mask.shape[0] * factor)))
        small_image = cv2.resize(np.ascontiguousarray(image[..., :3]), size, interpolation=cv2.INTER_AREA)
        small_mask = cv2.resize(mask.astype(np.float32), size, interpolation=cv2.INTER_AREA) >= 0.5
        if probability is not None:
            probability = cv2.resize(np.asarray(probability, dtype=np.float32), size, interpolation=cv2.INTER_AREA)
    else:
        small_image, small_mask = np.ascontiguousarray(image[..., :3]), mask
    if not small_mask.any():
        return mask, {}
    cut, added, agreement = _pieces_to_change(small_image, small_mask, probability, paired_colours)
    if factor < 1.0:
        full = (mask.shape[1], mask.shape[0])
        cut = cv2.resize(cut.astype(np.uint8), full, interpolation=cv2.INTER_NEAREST) > 0
        added = cv2.resize(added.astype(np.uint8), full, interpolation=cv2.INTER_NEAREST) > 0
    repaired = (mask & ~cut) | added
    summary = {"outline_agreement": round(agreement, 4), "cut_px": int(np.count_nonzero(mask & cut)),
               "added_px": int(np.count_nonzero(added & ~mask))}
    return repaired, summary


def _pieces_to_change(image: np.ndarray, mask: np.ndarray, probability: np.ndarray | None,
                      paired_colours: bool) -> tuple[np.ndarray, np.ndarray, float]:
    """(pixels to cut, pixels to add, the line's outline agreement) on the working image."""
    nothing = np.zeros_like(mask)
    fit = fit_mirror(mask, 0.0, COARSE_TILTS, OBJECT_BENDS, outline=True)
    fit = fit_mirror(mask, np.deg2rad(fit.tilt_deg), (0.0,) + FINE_TILTS, OBJECT_BENDS, outline=True, grid=FINE_GRID)
    if fit.agreement < MIN_OUTLINE_AGREEMENT:
        return nothing, nothing, fit.agreement
    partner_x, partner_y = fit.partners(mask.shape)
    mirrored = cv2.remap(mask.astype(np.uint8), partner_x, partner_y, cv2.INTER_NEAREST, borderValue=0) > 0
    radius = max(2, round(PIECE_RADIUS * mask_extent(mask)))
    _count, pieces = cv2.connectedComponents((mask & ~mirrored).astype(np.uint8), connectivity=8)
    cores = cv2.morphologyEx((mask & ~mirrored).astype(np.uint8), cv2.MORPH_OPEN, disc(radius)) > 0
    chunky = [int(i) for i in np.unique(pieces[cores]) if i > 0]
    if not chunky:
        return nothing, nothing, fit.agreement

    lab = cv2.cvtColor(image, cv2.COLOR_RGB2LAB).astype(np.float32)
    colour_gap = np.linalg.norm(lab - cv2.remap(lab, partner_x, partner_y, cv2.INTER_LINEAR), axis=2)
    symmetric = mask & mirrored
    around = (cv2.dilate(mask.astype(np.uint8), disc(3 * radius)) > 0) & ~(cv2.dilate((mask | mirrored).astype(np.uint8), disc(2)) > 0)
    if not symmetric.any() or not around.any():
        return nothing, nothing, fit.agreement
    object_samples = _object_samples(symmetric, colour_gap, paired_colours)
    to_object = distance_to_colours(lab, lab[object_samples if object_samples.any() else symmetric])
    to_background = distance_to_colours(lab, lab[around])
    gradient = _gradient(lab)
    inside = cv2.erode(symmetric.astype(np.uint8), disc(2)) > 0
    inside_gradient = max(float(np.median(gradient[inside])) if inside.any() else 1.0, 1.0)
    from_line = fit.distance_to_line(mask.shape)

    cut, added = nothing.copy(), nothing.copy()
    for index in chunky:
        piece = pieces == index
        image_of_piece = cv2.remap(piece.astype(np.uint8), partner_x, partner_y, cv2.INTER_NEAREST, borderValue=0) > 0
        beyond = image_of_piece & ~mask
        if not beyond.any():
            continue
        beyond_object = float(np.median(to_object[beyond]))
        beyond_background = float(np.median(to_background[beyond]))
        on_line = float(from_line[piece].min()) <= ON_LINE
        if beyond_background - beyond_object >= CLEAR_GAP and (on_line or float(np.median(colour_gap[piece])) < SAME_COLOUR):
            added |= beyond
            continue
        meeting = piece & (cv2.dilate((mask & ~piece).astype(np.uint8), disc(1)) > 0)
        # A piece apart from the rest is set off from it by background already.
        along_edge = not meeting.any() or float(np.median(gradient[meeting])) >= EDGE_RATIO * inside_gradient
        piece_to_object = float(np.median(to_object[piece]))
        object_coloured = piece_to_object < OWN_COLOUR or piece_to_object < OBJECT_NEARER * float(np.median(to_background[piece]))
        doubted = probability is not None and float(probability[piece].mean()) < DOUBTED_P
        if (not on_line and along_edge and beyond_background < beyond_object
                and (not object_coloured or (doubted and beyond_object - beyond_background >= CLEAR_GAP))):
            cut |= piece
    return cut, added, fit.agreement


def _object_samples(symmetric: np.ndarray, colour_gap: np.ndarray, paired_colours: bool) -> np.ndarray:
    """Where the object's colours are read: its symmetric part, one pixel in; with ``paired_colours``
    only where a pixel's colour matches its mirror partner's too.

    Blobs behind the object on both sides pass for symmetric (a violet blob left of a bass's
    neck facing a cyan one on the right), and read there their colours count as the object's
    own, so their pieces escape the cut. A flat face lit evenly (a guitar's) looks alike on
    both sides, so pairs that differ are not the object; a plane's dihedral wings catch the
    light differently and lose their own colours that way (families choose it:
    ``mirror_repair_paired_colours``)."""
    inside = cv2.erode(symmetric.astype(np.uint8), disc(1)) > 0
    if not paired_colours:
        return inside
    paired = inside & (colour_gap < SAME_COLOUR)
    return paired if np.count_nonzero(paired) >= MIN_PAIRED_PIXELS else inside


def _gradient(lab: np.ndarray) -> np.ndarray:
    """Colour gradient magnitude (CIELAB, after a light blur against sensor noise)."""
    smooth = cv2.GaussianBlur(lab, (0, 0), 1.0)
    across = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3)
    down = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3)
    return np.sqrt((across**2 + down**2).sum(axis=2))
