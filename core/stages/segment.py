"""Object segmentation (paper 3.1.1): training-free defaults of the segmenter chain.

The chain (``frontal3d_segment`` hook) asks, in order: the user's mask, the alpha
channel, learned segmenters from plugins, then :func:`grabcut_segment`, which needs no
training: a smooth background model fitted from the image border inwards, with edge and
texture cues, seeds OpenCV's GrabCut. Once the classifier has placed the family's
templates on that mask, :func:`refine_with_shape_prior` cuts again with them as shape
priors, for clutter that fooled the first pass.
"""

from __future__ import annotations

from typing import Mapping

import cv2
import numpy as np
from scipy import ndimage
from skimage import morphology

from frontal3d.masks import disc, mask_extent
from frontal3d.render import TemplateRenders
from frontal3d.stages.align import warp_mask
from frontal3d.stages.classify import Agreement, silhouette_agreement


#: Components smaller than this fraction of the largest are clutter, not objects.
MIN_OBJECT_FRACTION = 0.15
#: Components smaller than this many pixels are specks whatever the largest is.
MIN_OBJECT_PIXELS = 16
#: Long side of the image GrabCut first runs on (speed); the edge is refined at full size.
GRABCUT_SIZE = 400
#: Long side above which the full-resolution edge refinement runs on a downscaled copy.
REFINE_MAX_SIZE = 1600
#: Width of the image border, as a fraction of the long side, taken as background.
BORDER_FRACTION = 0.03
#: Fits of the smooth background model (the first from the border alone).
BACKGROUND_FIT_ROUNDS = 4
#: Seeds reach this fraction of the long side; beyond it lies definite background.
SEED_REACH = 0.1
#: Texture below this fraction of the border's quietest marks a smooth (object) surface.
SMOOTHNESS_RATIO = 0.6
#: A frame (border, letterbox) is at most this fraction of the image on each side.
MAX_FRAME_FRACTION = 0.15
#: Largest per-channel standard deviation along a line of a uniform frame.
FRAME_UNIFORMITY = 8.0
#: Colour step from a frame to the picture inside it.
FRAME_CONTRAST = 20.0
#: Colour clusters are fitted to at most about this many sampled pixels (speed).
MAX_CLUSTER_SAMPLES = 20000
#: Multiple of the border's colour spread (98th percentile) beyond which a pixel is
#: surely not background.
STRONG_DIFFERENCE = 3.0
#: On a textured background the border's spread is the texture's own range: beyond it by
#: this much (Lab units), at most, a pixel is surely not background however wide the
#: range. (A spread from several colour regions, a scene or blobs, keeps the full margin.)
MAX_DIFFERENCE_MARGIN = 15.0
#: Median fine-scale texture of the border (lightness units, :func:`_fine_texture`) from
#: which the background counts as textured; sensor noise alone gives about 0.5.
TEXTURED_BORDER = 1.5
#: A weakly different pixel is object-like when its distance to the object's colours is
#: below this multiple of its distance to the background's.
OBJECT_LIKENESS = 2.0
#: Holes smaller than this fraction of the object are filled (specular spots, logos).
MAX_FILLED_HOLE = 0.01
#: Below this fraction of the image, what GrabCut found is noise, not an object.
MIN_FOREGROUND = 0.01
#: A learned p(object) from this up marks the network's object, at its widest.
LEARNED_UNLIKELY = 0.1
#: How far (fraction of the long side) a seed region may lie from the learned segmenter's
#: object and still count as part of it (it sees the photo at 96 px: edges blur away).
LEARNED_REACH = 0.03
#: Median distance (Lab units) from the learned object's colours beyond which a seed piece
#: out of the network's reach is something else (a blob behind the object).
FOREIGN_COLOUR = 10.0
#: The same distance for the pieces GrabCut grew beyond the network's reach: higher, since
#: what it grew is often the object's own surface under other light (a bonnet's reflection,
#: 12-15 on the shared car photos), while a blob it grew into lies far off (30-55).
FOREIGN_GROWTH_COLOUR = 20.0
#: GrabCut iterations of the second cut once foreign pieces of its foreground are removed.
FOREIGN_ITERATIONS = 2
#: At most this many such cuts: a cut can grow the foreground further into the same blob
#: (its colour model changed), and the next cut takes that back.
FOREIGN_ROUNDS = 3
#: At most this many times the sure background beyond the seeds' reach moves out to the
#: reach of GrabCut's foreground where that foreground runs up against it.
REACH_ROUNDS = 3
#: Doubted colours (:func:`_cut_doubted_colours`): GrabCut's foreground is split into this many
#: colours (k-means, Lab); a colour the network believes has mean p(object) >= 0.5 over its pixels
#: (or, when no colour reaches 0.5, at least :data:`BELIEVED_SHARE` of the best colour's mean and
#: :data:`BELIEVED_FLOOR`), one it doubts has a mean below :data:`DOUBTED_COLOUR_P` and a hue (a, b)
#: more than :data:`DOUBTED_CHROMA` from every believed one the network is sure of (:func:`_own_colours`;
#: every believed one when it is sure of none). Its pixels at p < :data:`DOUBTED_PIXEL_P`
#: (opened 7 px, so no edge blend) become sure background. Chosen on the odd-indexed renders.
FOREGROUND_COLOURS = 8
DOUBTED_COLOUR_P = 0.45
DOUBTED_PIXEL_P = 0.25
DOUBTED_CHROMA = 20.0
BELIEVED_SHARE = 0.8
BELIEVED_FLOOR = 0.3
#: Background colours (:func:`_cut_background_colours`): a foreground colour is the network's
#: object's own when at least :data:`CORE_SHARE` of its pixels have p(object) above
#: :data:`CORE_P`. Another colour, more than :data:`DOUBTED_CHROMA` in hue from every such one, of
#: which the background shows at least :data:`BACKGROUND_COLOUR_SHARE` times as many pixels (at
#: p < :data:`DOUBTED_PIXEL_P`, within :data:`COLOUR_MATCH` Lab units of it) as the foreground,
#: loses its pixels below p :data:`KEEP_P` to sure background. Chosen on the odd-indexed renders.
#: The guitar network trained with people (2026-12-07) is sure of less: psb_m628's wood has 26 %
#: of its pixels above 0.9, the red blob beside it 3 %, so no colour was the object's and the
#: blob stayed. Below :data:`CORE_SHARE`, colours at half the surest one's share count
#: (:func:`_own_colours`): guitar blobs, seeds 0-2, 0.899 -> 0.912, car and airplane unchanged.
CORE_P = 0.9
CORE_SHARE = 0.5
BACKGROUND_COLOUR_SHARE = 1.0
COLOUR_MATCH = 10.0
KEEP_P = 0.95
#: Strips (:func:`_fill_vouched_strips`): gaps a closing of this fraction of the long side fills
#: in GrabCut's foreground, where p(object) > :data:`STRIP_P`, join it when each piece is at
#: least :data:`STRIP_ELONGATION` times as long as it is wide. Chosen on the odd-indexed renders.
STRIP_GAP = 0.008
STRIP_P = 0.5
STRIP_ELONGATION = 5.0
#: Unvouched pieces (:func:`_cut_unvouched_pieces`): GrabCut's foreground where the network gives
#: p(object) below :data:`UNVOUCHED_P`, opened by a disc of :data:`UNVOUCHED_OPENING` of the long side,
#: is cut piece by piece when a piece's median colour lies within :data:`COLOUR_MATCH` of the
#: background around the object (within the learned reach, p < :data:`LEARNED_UNLIKELY`) and nearer
#: to it than to the object's sure colours (p > :data:`CORE_P`), the test :func:`_fill_vouched_strips`
#: makes of a gap. Chosen on the car renders' even and odd halves and the six shared photos, at
#: 0.03; raised to 0.1 (the network's own "unlikely", :data:`LEARNED_UNLIKELY`) because on a flat
#: black backdrop the network's haze stays at 0.03-0.1 and GrabCut's band of backdrop around a
#: guitar was never cut (people composites 0.679 -> 0.716; every mask benchmark within 0.0004).
UNVOUCHED_P = 0.1
UNVOUCHED_OPENING = 0.01
#: Thin parts (:func:`_sure_thin_parts`): what an opening by a disc of :data:`THIN_PART` of the long
#: side takes off the network's object (p above each of :data:`THIN_PART_P`), in pieces at least
#: :data:`THIN_PART_LENGTH` of the network's object (p > 0.5) long; their centre lines are sure foreground.
THIN_PART = 0.02
THIN_PART_P = (0.5, 0.7, 0.9)
THIN_PART_LENGTH = 0.25
#: Faces (:func:`without_faces`): the object entering a head and leaving it again, each time in a
#: run of at least FACE_RUN_PIXELS narrower than this share of the head's size, crosses the face
#: (a guitar's neck in front of it); the strip between the two runs stays object.
FACE_CROSSING_WIDTH = 0.6
FACE_RUN_PIXELS = 3


def mask_from_alpha(image: np.ndarray) -> np.ndarray | None:
    """The alpha channel as the mask, or None when there is none or it is uniform (fully opaque or
    fully transparent: it outlines nothing, and the segmenters look at the colours instead)."""
    if image.ndim != 3 or image.shape[2] != 4:
        return None
    alpha = image[..., 3]
    if alpha.min() == alpha.max():
        return None
    return alpha > 127


def without_faces(mask: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``mask`` less people's faces (``occluders.detect_faces``): the learned segmenter takes
    skin for wood, so a face beside a guitar joins it and its texture ends up on the model.
    Where the object crosses a head in a thin strip (a neck in front of the face), the strip
    between where it enters the head and where it leaves stays object."""
    mask = np.asarray(mask, dtype=bool)
    faces = np.asarray(faces, dtype=bool)
    kept = mask & ~faces
    count, heads, stats, _ = cv2.connectedComponentsWithStats(faces.astype(np.uint8))
    for label in range(1, count):
        head = heads == label
        size = max(stats[label, cv2.CC_STAT_WIDTH], stats[label, cv2.CC_STAT_HEIGHT])
        ring = (cv2.dilate(head.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0) & ~head
        run_count, runs = cv2.connectedComponents((kept & ring).astype(np.uint8), connectivity=8)
        thin = [points for points in (np.argwhere(runs == k) for k in range(1, run_count))
                if len(points) >= FACE_RUN_PIXELS and np.ptp(points[:, 0]) + np.ptp(points[:, 1]) < FACE_CROSSING_WIDTH * size]
        if len(thin) == 2:
            strip = np.zeros(mask.shape, np.uint8)
            cv2.fillConvexPoly(strip, cv2.convexHull(np.vstack(thin)[:, ::-1].astype(np.int32)), 1)
            kept |= mask & head & (strip > 0)
    return kept


def split_objects(mask: np.ndarray) -> list[np.ndarray]:
    """Connected components of ``mask``, largest first, specks and small clutter dropped."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(np.asarray(mask, dtype=np.uint8), connectivity=8)
    if count <= 1:
        return []
    areas = stats[1:, cv2.CC_STAT_AREA]
    order = np.argsort(-areas, kind="stable")
    floor = max(MIN_OBJECT_PIXELS, MIN_OBJECT_FRACTION * areas[order[0]])
    return [labels == (i + 1) for i in order if areas[i] >= floor]


def grabcut_segment(image: np.ndarray, iterations: int = 5, object_probability: np.ndarray | None = None) -> np.ndarray | None:
    """Segment the object(s) in front of a plain, graded or mildly cluttered background.

    A smooth background (a low-order polynomial per Lab channel, fitted robustly from
    the border inwards) is subtracted, so a light-grey object on a light gradient stands
    out as much as a red one on white. Pixels far from that model seed GrabCut, which
    runs on the flattened image at a working size; its edge is then refined in a thin
    band at full resolution. Returns None when
    nothing object-like stands out (under 1 % of the image, or a region touching all
    four borders, which is background the model could not explain). A uniform frame
    around the picture (a print border, a letterbox) is set aside first.

    ``object_probability`` (a learned segmenter's p(object) on the image grid) turns
    seed regions away from the network's object (blobs) into sure background and adds the
    object the colour cues missed: see :func:`_learned_seeds`.
    """
    rgb = np.ascontiguousarray(image[..., :3], dtype=np.uint8)
    rows, cols = _inside_frame(rgb)
    probability = None if object_probability is None else np.asarray(object_probability, np.float32)[rows, cols]
    inner = _segment_unframed(np.ascontiguousarray(rgb[rows, cols]), iterations, probability)
    if inner is None:
        return None
    mask = np.zeros(rgb.shape[:2], bool)
    mask[rows, cols] = inner
    return mask


def _segment_unframed(rgb: np.ndarray, iterations: int, probability: np.ndarray | None = None) -> np.ndarray | None:
    """:func:`grabcut_segment` on a picture whose border is its background."""
    height, width = rgb.shape[:2]
    scale = min(1.0, GRABCUT_SIZE / max(height, width))
    small_size = (max(1, round(width * scale)), max(1, round(height * scale)))
    small = cv2.resize(rgb, small_size, interpolation=cv2.INTER_AREA)
    lab = cv2.cvtColor(small, cv2.COLOR_RGB2LAB).astype(np.float32)
    border = _border_mask(small.shape[:2])
    background = _smooth_background(lab, border)
    flattened = np.clip(lab - background + background[border].mean(axis=0), 0, 255).astype(np.uint8)
    small_probability = None if probability is None else cv2.resize(probability, small_size, interpolation=cv2.INTER_LINEAR)
    labels = _initial_labels(lab, background, border, small_probability)
    if labels is None:
        return None
    init, beyond_reach = labels
    _grabcut(flattened, init, iterations)
    if small_probability is not None:
        _widen_reach(init, beyond_reach, flattened)
        seen = cv2.GaussianBlur(lab, (0, 0), 1.5)
        _cut_foreign_growth(init, small_probability, seen, flattened)
        _cut_doubted_colours(init, small_probability, seen, flattened)
        _cut_background_colours(init, small_probability, seen, flattened)
        _cut_unvouched_pieces(init, small_probability, seen, flattened)
        _fill_vouched_strips(init, small_probability, seen)
    found = _clean(_foreground(init))
    if found.mean() < MIN_FOREGROUND or _touches_all_borders(found):
        return None
    refined = _refine_edge(rgb, found)
    refined = _clean(refined)
    if not refined.any():
        return None
    return refined


def _inside_frame(rgb: np.ndarray) -> tuple[slice, slice]:
    """Rows and columns inside a uniform frame or letterbox, which would pass for the background.

    A side's frame is its run of uniform lines, but only when the first line after it
    differs from the frame nearly everywhere: on a plain background the first
    non-uniform line is where the object starts, and that differs only in part.
    """
    height, width = rgb.shape[:2]
    image = rgb.astype(np.float32)
    sides = {"top": image, "bottom": image[::-1], "left": image.transpose(1, 0, 2), "right": image.transpose(1, 0, 2)[::-1]}
    depth = {}
    for side, lines in sides.items():
        lines = lines[: max(2, int(MAX_FRAME_FRACTION * len(lines))) + 1]
        uniform = lines.std(axis=1).max(axis=1) < FRAME_UNIFORMITY
        count = int(np.argmin(uniform)) if not uniform.all() else 0
        following_differs = count > 0 and (np.abs(lines[count] - lines[count - 1].mean(axis=0)).max(axis=1) > FRAME_CONTRAST).mean() > 0.8
        depth[side] = count if following_differs else 0
    return slice(depth["top"], height - depth["bottom"]), slice(depth["left"], width - depth["right"])


def _border_mask(shape: tuple[int, int]) -> np.ndarray:
    border = max(2, round(BORDER_FRACTION * max(shape)))
    mask = np.zeros(shape, bool)
    mask[:border] = mask[-border:] = True
    mask[:, :border] = mask[:, -border:] = True
    return mask


def _smooth_background(lab: np.ndarray, border: np.ndarray) -> np.ndarray:
    """A degree-2 polynomial per channel fitted to the background, iteratively trimmed.

    The first fit uses the border only; later fits use every pixel the current model
    explains (within 3 border spreads), so the object drops out and gradients and
    vignettes are followed across the whole image.
    """
    height, width = lab.shape[:2]
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    x, y = 2 * xs / max(width - 1, 1) - 1, 2 * ys / max(height - 1, 1) - 1
    basis = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=-1).reshape(-1, 6)
    # Fit on every second pixel (the model is smooth), evaluate everywhere.
    sample_basis, values = basis.reshape(height, width, 6)[::2, ::2].reshape(-1, 6), lab[::2, ::2].reshape(-1, 3)
    on_border = border[::2, ::2].reshape(-1)
    weights = on_border.astype(np.float32)
    for _ in range(BACKGROUND_FIT_ROUNDS):
        weighted = sample_basis * weights[:, None]
        coefficients = np.linalg.solve(weighted.T @ sample_basis + 1e-3 * np.eye(6), weighted.T @ values)
        distance = np.linalg.norm(values - sample_basis @ coefficients, axis=1)
        spread = float(np.percentile(distance[on_border], 90)) + 1.0
        weights = (distance < 3 * spread).astype(np.float32)
    return (basis @ coefficients.astype(np.float32)).reshape(lab.shape)


def _initial_labels(lab: np.ndarray, background: np.ndarray, border_mask: np.ndarray,
                    probability: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """GrabCut's initial label map and its sure background that only distance put there (beyond
    the seeds' reach); None when no pixel differs from the background.

    Probable foreground: what the background model cannot explain (weak differences
    too, where they are solid areas touching strong ones: a wing barely lighter than
    the sky), smooth surfaces on a textured background, and regions closed off by
    strong edges (an object of the background's own colour still has an outline).
    Definite background: the border and whatever lies far from all of these. With a learned
    p(object), the network's whole object (p >= :data:`LEARNED_UNLIKELY`) counts as seeded
    for that distance: its surest part alone may be a guitar's neck without the body; the
    centre lines of its thin parts are sure foreground (:func:`_sure_thin_parts`).
    """
    residual = lab - background
    # Distance to the nearest border colour after flattening: one colour for a plain or
    # graded background, a few for a scene (grass, kerb, road).
    smoothed = cv2.GaussianBlur(residual, (0, 0), 1.5)
    distance = distance_to_colours(smoothed, smoothed[border_mask])
    # Border pixels are the background's own spread (noise, texture): beyond it is "different".
    spread = float(np.percentile(distance[border_mask], 98))
    margin = (STRONG_DIFFERENCE - 1) * spread
    texture = _fine_texture(residual[..., 0])
    textured = float(np.median(texture[border_mask])) >= TEXTURED_BORDER
    threshold = max(6.0, spread + (min(margin, MAX_DIFFERENCE_MARGIN) if textured else margin))
    different = cv2.morphologyEx((distance > threshold).astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)) > 0
    # Hysteresis: weaker differences (from the background's median colour, which unlike
    # its clusters does not also cover a surface slightly off it) count where they look
    # like the strong ones and form solid areas touching them: a wing barely lighter
    # than the sky joins its fuselage, a faint shape of another colour does not.
    offset = np.linalg.norm(smoothed - np.median(smoothed[border_mask], axis=0), axis=2)
    weak_threshold = max(4.0, float(np.percentile(offset[border_mask], 90)))
    core = cv2.erode(different.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0  # no edge blends
    if core.any():
        object_like = distance_to_colours(smoothed, smoothed[core]) < OBJECT_LIKENESS * distance
        weak = cv2.morphologyEx(((offset > weak_threshold) & object_like).astype(np.uint8), cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7)))
        _, weak_labels = cv2.connectedComponents(weak | different.astype(np.uint8), connectivity=8)
        different |= np.isin(weak_labels, np.unique(weak_labels[different])) & (weak_labels > 0)
    candidates = (different | _smoother_than_background(texture, border_mask) | _enclosed_by_edges(lab, border_mask)) & ~border_mask
    salient = np.zeros_like(different)
    for component in split_objects(candidates):
        salient |= component
    sure_background = np.zeros_like(salient)
    if probability is not None:
        salient, sure_background = _learned_seeds(salient, probability, cv2.GaussianBlur(lab, (0, 0), 1.5))
    init = np.full(lab.shape[:2], cv2.GC_PR_BGD, np.uint8)
    seeded = salient if probability is None else salient | (probability >= LEARNED_UNLIKELY)
    near = _dilated(seeded, _seed_reach(lab.shape[:2]))
    init[~near | sure_background] = cv2.GC_BGD
    init[salient] = cv2.GC_PR_FGD
    if probability is not None:
        init[_sure_thin_parts(probability, distance, spread)] = cv2.GC_FGD
    init[border_mask] = cv2.GC_BGD
    if (init == cv2.GC_PR_FGD).mean() < MIN_FOREGROUND / 2:
        return None
    return init, ~near & ~sure_background & ~border_mask


def _sure_thin_parts(probability: np.ndarray, distance: np.ndarray, spread: float) -> np.ndarray:
    """The centre lines of the thin parts the network sees (a guitar's neck, a tail boom) whose
    colour stands out from the background's: sure foreground for GrabCut, whose smoothness term
    otherwise cuts a part a few pixels wide wherever its colour comes near the background's (a
    grey fretboard on a beige carpet).

    A part is thin where an opening by a disc of :data:`THIN_PART` of the long side takes it off
    the network's object, at any of :data:`THIN_PART_P`: the network's blur widens a part at low
    p, and at high p it may break up a part it sees less surely (a neck near its headstock). A
    line stands out when its median ``distance`` to the border's colours exceeds ``spread``, the
    border's own (the network's p also strays onto grain, in thin fragments of grain's colour).
    """
    lines = np.zeros(probability.shape, bool)
    radius = max(1, round(THIN_PART * max(probability.shape)))
    shortest = THIN_PART_LENGTH * mask_extent(probability > 0.5)
    for level in THIN_PART_P:
        seen = (probability > level).astype(np.uint8)
        thin = (seen > 0) & (cv2.morphologyEx(seen, cv2.MORPH_OPEN, disc(radius)) == 0)
        _, pieces, stats, _ = cv2.connectedComponentsWithStats(thin.astype(np.uint8), connectivity=8)
        length = np.maximum(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
        long_parts = 1 + np.flatnonzero(length[1:] >= shortest)
        if len(long_parts):
            # Three pixels wide, so that the opening that clears specks later leaves it.
            centre = _pruned(morphology.skeletonize(np.isin(pieces, long_parts)), 2 * radius)
            lines |= _dilated(centre, 1) & (seen > 0)
    count, pieces = cv2.connectedComponents(lines.astype(np.uint8), connectivity=8)
    if count < 2:
        return lines
    index = np.arange(1, count)
    standing_out = np.asarray(ndimage.median(distance[lines], pieces[lines], index)) > spread
    return np.isin(pieces, index[standing_out])


def _pruned(skeleton: np.ndarray, steps: int) -> np.ndarray:
    """``skeleton`` without its spurs up to ``steps`` pixels long (a region's skeleton branches
    into each corner, off a neck's end and into a blob beside a wing); the ends of its main
    lines shorten by as much."""
    line = skeleton.astype(np.uint8)
    neighbours = np.ones((3, 3), np.float32)
    neighbours[1, 1] = 0
    for _ in range(steps):
        ends = (line > 0) & (cv2.filter2D(line, cv2.CV_32F, neighbours, borderType=cv2.BORDER_CONSTANT) <= 1)
        if not ends.any():
            break
        line[ends] = 0
    return line > 0


def _seed_reach(shape: tuple[int, ...]) -> int:
    """:data:`SEED_REACH` in pixels of an image of ``shape``."""
    return max(3, round(SEED_REACH * max(shape)))


def _widen_reach(labels: np.ndarray, beyond_reach: np.ndarray, flattened: np.ndarray) -> None:
    """Where GrabCut's foreground (``labels``, in place) runs up against the sure background that
    only the seeds' reach put there (``beyond_reach``), that background moves out to the reach of
    the foreground and GrabCut cuts again, up to :data:`REACH_ROUNDS` times.

    Seeded by the network, the seeds can be its blurred object alone (a white plane's fuselage
    without the wing tips, over colours the border also shows), and the reach drawn around them
    cut the object off along an arc; the colour model GrabCut learned decides instead.
    """
    reach = _seed_reach(labels.shape)
    beyond_reach = beyond_reach.copy()
    for _ in range(REACH_ROUNDS):
        found = _foreground(labels)
        if np.count_nonzero(found & _dilated(beyond_reach, 1)) < MIN_OBJECT_PIXELS:
            return
        released = beyond_reach & _dilated(found, reach)
        labels[released] = cv2.GC_PR_BGD
        beyond_reach &= ~released
        _grabcut(flattened, labels, FOREIGN_ITERATIONS)


def _learned_seeds(salient: np.ndarray, probability: np.ndarray, colours: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The classical seeds corrected by a learned p(object): (probable object, sure background).

    The network sees the photo at low resolution: it knows where the object is, but blurs
    its edge and misses thin or unusual parts (a tailplane, a pick-up's bed), while the
    colour cues know the edge but take blobs for objects. So seed regions that do not
    reach within :data:`LEARNED_REACH` of its object (p >= :data:`LEARNED_UNLIKELY`)
    become sure background, and so do the pieces of the others that lie beyond that
    reach unless their colours (``colours``, Lab as seen: on a gradient the flattened
    colours of one surface differ from place to place) are the network's object's
    (a tailplane is the fuselage's colour, a blob behind the object is not): see
    :func:`_foreign_pieces`. Its object (p > 0.5) is added; everything else is left to
    GrabCut as without the network.
    """
    near_object = _near_learned_object(probability)
    _, labels = cv2.connectedComponents(salient.astype(np.uint8), connectivity=8)
    kept = np.isin(labels, np.unique(labels[salient & near_object])) & salient
    kept &= ~_foreign_pieces(kept & ~near_object, kept & (probability > 0.5), colours)
    return kept | (probability > 0.5), salient & ~kept


def _near_learned_object(probability: np.ndarray) -> np.ndarray:
    """Within :data:`LEARNED_REACH` of the network's object (p >= :data:`LEARNED_UNLIKELY`)."""
    return _dilated(probability >= LEARNED_UNLIKELY, _learned_reach(probability.shape))


def _learned_reach(shape: tuple[int, ...]) -> int:
    """:data:`LEARNED_REACH` in pixels of an image of ``shape``."""
    return max(2, round(LEARNED_REACH * max(shape)))


def _cut_foreign_growth(labels: np.ndarray, probability: np.ndarray, colours: np.ndarray, flattened: np.ndarray) -> None:
    """GrabCut's foreground (``labels``, in place) without the pieces it grew beyond the network's
    reach in colours not its object's (a blob's far side, once a seed near the object taught the
    foreground model its colour): they become sure background and GrabCut cuts again, up to
    :data:`FOREIGN_ROUNDS` times while it grows such pieces anew."""
    far_off, learned_object = ~_near_learned_object(probability), probability > 0.5
    for _ in range(FOREIGN_ROUNDS):
        found = _foreground(labels)
        foreign = _foreign_pieces(found & far_off, found & learned_object, colours, FOREIGN_GROWTH_COLOUR)
        if not foreign.any():
            return
        labels[foreign] = cv2.GC_BGD
        _grabcut(flattened, labels, FOREIGN_ITERATIONS)


def _cut_doubted_colours(labels: np.ndarray, probability: np.ndarray, colours: np.ndarray, flattened: np.ndarray) -> None:
    """GrabCut's foreground (``labels``, in place) without its colours the network doubts (see
    :data:`FOREGROUND_COLOURS`), then GrabCut cuts again.

    A blob touching the object lies within the network's reach, so :func:`_cut_foreign_growth`
    never tests it, and the network's blurred edge lends it p > 0.5 near the object: judged per
    pixel, its colour looks like the object's. Judged per colour of the whole foreground, most of
    its pixels have low p, while the object's colours are believed on most of theirs.

    Hue is measured from the believed colours the network is also sure of (:func:`_own_colours`)
    when there are any: the blend of object and background along the object's edge is believed
    too (p 0.55 where a glider's wing meets grass), and it lay within 20 of the grass, so a faint
    shape of grass colour over half the image was kept.
    """
    found = _foreground(labels)
    clusters = _foreground_colours(found, colours)
    if clusters is None:
        return
    centres, nearest = clusters[0], clusters[1][found]
    counts = np.bincount(nearest, minlength=len(centres))
    belief = np.bincount(nearest, weights=probability[found], minlength=len(centres)) / np.maximum(counts, 1)
    # An object the network sees faintly (a glider's thin wings, a guitar body over clutter) may
    # have no colour at 0.5, while a blob touching it has far less: its best colours stand for it.
    believed = (belief >= min(0.5, max(BELIEVED_FLOOR, BELIEVED_SHARE * belief.max()))) & (counts > 0)
    if not believed.any():
        return
    own = believed & _own_colours(nearest, probability[found], len(centres))
    doubted = (belief < DOUBTED_COLOUR_P) & (_hue_apart(centres, own if own.any() else believed) > DOUBTED_CHROMA)
    cut = np.zeros_like(found)
    cut[found] = doubted[nearest] & (probability[found] < DOUBTED_PIXEL_P)
    cut = cv2.morphologyEx(cut.astype(np.uint8), cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))) > 0
    _cut_and_regrow(labels, cut, flattened)


def _cut_background_colours(labels: np.ndarray, probability: np.ndarray, colours: np.ndarray, flattened: np.ndarray) -> None:
    """GrabCut's foreground (``labels``, in place) without its colours that are the background's
    (see :data:`CORE_P`), then GrabCut cuts again.

    The network sees a blob beside the object through its 96 px blur and vouches for the part
    next to it (p 0.86 on a red blob beside a bass's body), so per colour that part looks
    believed and :func:`_cut_doubted_colours` keeps it. But the network is sure (p > 0.9) of
    few of its pixels, while the object's own colours are sure on most of theirs (or, from a
    network that hedges everywhere, on far more of theirs: :func:`_own_colours`), and the
    blob goes on behind or beyond the object, where the background shows more of its colour
    than the foreground holds. An object's own colour is rarely scattered that widely around it.
    """
    found = _foreground(labels)
    clusters = _foreground_colours(found, colours)
    if clusters is None:
        return
    centres, nearest, distance = clusters
    inside = np.bincount(nearest[found], minlength=len(centres))
    own = _own_colours(nearest[found], probability[found], len(centres))
    if not own.any():
        return
    background = ~found & (probability < DOUBTED_PIXEL_P) & (distance < COLOUR_MATCH)
    outside = np.bincount(nearest[background], minlength=len(centres))
    foreign = (inside > 0) & ~own & (outside >= BACKGROUND_COLOUR_SHARE * inside) & (_hue_apart(centres, own) > DOUBTED_CHROMA)
    cut = found & foreign[nearest] & (probability < KEEP_P)
    cut = cv2.morphologyEx(cut.astype(np.uint8), cv2.MORPH_OPEN, disc(1)) > 0
    _cut_and_regrow(labels, cut, flattened)


def _cut_unvouched_pieces(labels: np.ndarray, probability: np.ndarray, colours: np.ndarray, flattened: np.ndarray) -> None:
    """GrabCut's foreground (``labels``, in place) without the pieces the network is sure are not
    object and whose colour is the background's around it (see :data:`UNVOUCHED_P`), then GrabCut
    cuts again.

    GrabCut overrules a confident network: a dark blob behind a dark car's flank, of the car's
    own tones, joins the foreground at p ~ 0 (a whole door's height above a sedan's roof). Low p
    alone does not make background: the network also misses real wheels and a pickup's bed in
    some renders (p < 0.03), and cutting every such piece took wheels off (car noise .993 -> .983).
    A piece of the background's colour does not: a wheel is the tyre's dark grey, nearer the
    car's sure colours than the wall's. Nearer is not enough: the tip of a red bonnet under white
    highlights lies 10-16 Lab units from a white studio wall and 17-21 from the car's sure red, and
    once cut, GrabCut's second cut took the whole bonnet (and a limousine's roof) with it.
    """
    found = _foreground(labels)
    ring = _dilated(found, _learned_reach(found.shape)) & ~found & (probability < LEARNED_UNLIKELY)
    sure = found & (probability > CORE_P)
    if np.count_nonzero(ring) < MIN_OBJECT_PIXELS or np.count_nonzero(sure) < MIN_OBJECT_PIXELS:
        return
    unvouched = found & (probability < UNVOUCHED_P)
    opening = disc(max(1, round(UNVOUCHED_OPENING * max(found.shape))))
    unvouched = cv2.morphologyEx(unvouched.astype(np.uint8), cv2.MORPH_OPEN, opening) > 0
    count, pieces = cv2.connectedComponents(unvouched.astype(np.uint8), connectivity=8)
    if count < 2:
        return
    index = np.arange(1, count)
    _cut_and_regrow(labels, np.isin(pieces, index[_shows_background(pieces, index, colours, ring, sure)]), flattened)


def _fill_vouched_strips(labels: np.ndarray, probability: np.ndarray, colours: np.ndarray) -> None:
    """Long thin gaps in GrabCut's foreground (``labels``, in place) that the network calls object
    become sure foreground (see :data:`STRIP_GAP`), unless they show the background's colour.

    A fuselage's shaded side is a strip of darker grey that GrabCut gives to a grey or dark
    background, though the network sees the whole fuselage (p 0.92 on such a strip). Only long
    thin pieces are filled: a closing also fills the wedge of a concave corner, where the
    network's blur is as sure and the gap is background. A thin piece whose median colour lies
    within :data:`COLOUR_MATCH` of the background around the object, and nearer to it than to
    the object's colours, is a real gap seen through (a wheel arch's crescent over a plain wall).
    Nothing bridges to the specks and clutter that :func:`_clean` drops later.
    """
    found = _foreground(labels)
    objects = split_objects(found)
    if not objects:
        return
    kept = np.logical_or.reduce(objects)
    closed = cv2.morphologyEx(kept.astype(np.uint8), cv2.MORPH_CLOSE, disc(max(1, round(STRIP_GAP * max(found.shape))))) > 0
    gaps = closed & ~found & (probability > STRIP_P) & ~_dilated(found & ~kept, 1)
    _, pieces, stats, _ = cv2.connectedComponentsWithStats(gaps.astype(np.uint8), connectivity=8)
    length = np.maximum(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
    width = stats[:, cv2.CC_STAT_AREA] / np.maximum(length, 1)
    strips = 1 + np.flatnonzero(STRIP_ELONGATION * width[1:] <= length[1:])
    if not len(strips):
        return
    ring = _dilated(kept, _learned_reach(found.shape)) & ~closed
    labels[np.isin(pieces, strips[~_shows_background(pieces, strips, colours, ring, kept)])] = cv2.GC_FGD


def _shows_background(pieces: np.ndarray, index: np.ndarray, colours: np.ndarray, ring: np.ndarray, own: np.ndarray) -> np.ndarray:
    """For each piece ``index`` of the label image ``pieces``: whether its median colour lies within
    :data:`COLOUR_MATCH` of the colours of ``ring`` (the background around the object) and nearer
    to them than to the colours of ``own`` (the object's)."""
    on_pieces = np.isin(pieces, index)
    seen = colours[on_pieces][:, None]
    to_background = np.asarray(ndimage.median(distance_to_colours(seen, colours[ring])[:, 0], pieces[on_pieces], index))
    to_object = np.asarray(ndimage.median(distance_to_colours(seen, colours[own])[:, 0], pieces[on_pieces], index))
    return (to_background < COLOUR_MATCH) & (to_background < to_object)


def _foreground_colours(found: np.ndarray, colours: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """:data:`FOREGROUND_COLOURS` k-means colours of the foreground, and for every pixel the nearest
    one and its distance; None when the foreground is too small to split."""
    samples = np.ascontiguousarray(colours[found], dtype=np.float32)
    if len(samples) < FOREGROUND_COLOURS * MIN_OBJECT_PIXELS:
        return None
    centres = _colour_clusters(samples, FOREGROUND_COLOURS)
    distance = np.sqrt(((colours.reshape(-1, 1, 3) - centres[None]) ** 2).sum(axis=2))
    return centres, distance.argmin(axis=1).reshape(found.shape), distance.min(axis=1).reshape(found.shape)


def _own_colours(nearest: np.ndarray, probability: np.ndarray, count: int) -> np.ndarray:
    """Which of ``count`` colours (``nearest``: each foreground pixel's) the network is sure are
    its object's: at least :data:`CORE_SHARE` of their pixels at p above :data:`CORE_P`, or, when
    no colour reaches that, at least :data:`CORE_SHARE` of the surest colour's share: a network
    that hedges everywhere still ranks its object's colours above a blob's. (Sure of no pixel at
    all, it makes every colour its own, so nothing is cut for hue.)"""
    pixels = np.bincount(nearest, minlength=count)
    sure = np.bincount(nearest, weights=probability > CORE_P, minlength=count) / np.maximum(pixels, 1)
    bar = CORE_SHARE if sure.max() >= CORE_SHARE else CORE_SHARE * sure.max()
    return (pixels > 0) & (sure >= bar)


def _hue_apart(centres: np.ndarray, chosen: np.ndarray) -> np.ndarray:
    """Each colour's distance in hue (a, b) to the nearest ``chosen`` one: shading moves a
    surface's lightness, not its hue."""
    chroma = centres[:, 1:]
    return np.sqrt(((chroma[:, None] - chroma[chosen][None]) ** 2).sum(axis=2)).min(axis=1)


def _cut_and_regrow(labels: np.ndarray, cut: np.ndarray, flattened: np.ndarray) -> None:
    """``cut`` becomes sure background and GrabCut cuts again (nothing when it is a speck)."""
    if np.count_nonzero(cut) < MIN_OBJECT_PIXELS:
        return
    labels[cut] = cv2.GC_BGD
    _grabcut(flattened, labels, FOREIGN_ITERATIONS)


def _foreign_pieces(far: np.ndarray, core: np.ndarray, colours: np.ndarray, threshold: float = FOREIGN_COLOUR) -> np.ndarray:
    """The pieces of ``far`` whose median colour distance to ``core``'s colours exceeds ``threshold``."""
    if not far.any() or np.count_nonzero(core) < MIN_OBJECT_PIXELS:
        return np.zeros_like(far)
    count, labels = cv2.connectedComponents(far.astype(np.uint8), connectivity=8)
    distance = distance_to_colours(colours[far][:, None], colours[core])[:, 0]
    medians = np.asarray(ndimage.median(distance, labels[far], np.arange(1, count)))
    return np.isin(labels, 1 + np.flatnonzero(medians > threshold))


def _smoother_than_background(texture: np.ndarray, border_mask: np.ndarray) -> np.ndarray:
    """Where a textured background (paper, fabric, sensor grain) gives way to a smooth surface
    (``texture``: :func:`_fine_texture` of the lightness)."""
    floor = float(np.percentile(texture[border_mask], 5))
    smooth = texture < SMOOTHNESS_RATIO * floor
    return cv2.morphologyEx(smooth.astype(np.uint8), cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))) > 0


def _fine_texture(lightness: np.ndarray) -> np.ndarray:
    """Local energy of the lightness' fine detail (band 1-3 px): grain, weave, print."""
    fine = cv2.GaussianBlur(lightness, (0, 0), 1.0) - cv2.GaussianBlur(lightness, (0, 0), 3.0)
    return np.sqrt(cv2.GaussianBlur(fine * fine, (0, 0), 4.0))


def _enclosed_by_edges(lab: np.ndarray, border_mask: np.ndarray) -> np.ndarray:
    """Regions closed off from the border by edges stronger than the border's own texture."""
    lightness = cv2.GaussianBlur(lab[..., 0], (0, 0), 1.0)
    gradient = np.hypot(cv2.Sobel(lightness, cv2.CV_32F, 1, 0), cv2.Sobel(lightness, cv2.CV_32F, 0, 1))
    low = max(8.0, float(np.percentile(gradient[border_mask], 99)))
    edges = cv2.Canny(np.clip(lightness, 0, 255).astype(np.uint8), low, 2 * low, L2gradient=True) > 0
    closed = cv2.morphologyEx(edges.astype(np.uint8), cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5)))
    _, labels = cv2.connectedComponents((closed == 0).astype(np.uint8), connectivity=4)
    outside = np.unique(labels[border_mask & (closed == 0)])
    enclosed = ~np.isin(labels, outside)
    return cv2.morphologyEx(enclosed.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)) > 0


def _refine_edge(rgb: np.ndarray, found_small: np.ndarray) -> np.ndarray:
    """Upsample the working-size mask and let GrabCut re-decide a thin band around its edge."""
    height, width = rgb.shape[:2]
    refine_scale = min(1.0, REFINE_MAX_SIZE / max(height, width))
    size = (max(1, round(width * refine_scale)), max(1, round(height * refine_scale)))
    target = rgb if refine_scale == 1.0 else cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
    soft = cv2.resize(found_small.astype(np.float32), size, interpolation=cv2.INTER_LINEAR)
    upsampled = soft > 0.5
    band = max(2, round(1.5 * max(size) / max(found_small.shape)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * band + 1,) * 2)
    inner = cv2.erode(upsampled.astype(np.uint8), kernel) > 0
    outer = cv2.dilate(upsampled.astype(np.uint8), kernel) > 0
    if inner.any() and (~outer).any():
        labels = np.where(upsampled, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)
        labels[inner] = cv2.GC_FGD
        labels[~outer] = cv2.GC_BGD
        ys, xs = np.nonzero(outer)
        pad = 4 * band
        y0, y1 = max(0, ys.min() - pad), min(size[1], ys.max() + pad + 1)
        x0, x1 = max(0, xs.min() - pad), min(size[0], xs.max() + pad + 1)
        crop = np.ascontiguousarray(labels[y0:y1, x0:x1])
        _grabcut(np.ascontiguousarray(target[y0:y1, x0:x1]), crop, 2)
        upsampled = np.zeros_like(upsampled)
        upsampled[y0:y1, x0:x1] = _foreground(crop)
    if refine_scale == 1.0:
        return upsampled
    return cv2.resize(upsampled.astype(np.float32), (width, height), interpolation=cv2.INTER_LINEAR) > 0.5


def _grabcut(rgb: np.ndarray, labels: np.ndarray, iterations: int) -> None:
    """cv2.grabCut in place on ``labels`` (mask initialisation), with fresh colour models."""
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.grabCut(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), labels, None, bgd, fgd, iterations, cv2.GC_INIT_WITH_MASK)


def _foreground(labels: np.ndarray) -> np.ndarray:
    return (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)


def distance_to_colours(image: np.ndarray, samples: np.ndarray, clusters: int = 6) -> np.ndarray:
    """Each pixel's distance to the nearest of a few k-means clusters of ``samples``' colours."""
    centres = _colour_clusters(samples, clusters)
    flat = image.reshape(-1, 1, 3)
    distance = np.sqrt(((flat - centres[None]) ** 2).sum(axis=2)).min(axis=1)
    return distance.reshape(image.shape[:2])


def _colour_clusters(samples: np.ndarray, clusters: int) -> np.ndarray:
    """Up to ``clusters`` k-means centres of ``samples``' colours (n x 3), seeded so every run agrees."""
    samples = np.ascontiguousarray(samples.reshape(-1, 3)[:: max(1, len(samples) // MAX_CLUSTER_SAMPLES)], dtype=np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 20, 1.0)
    cv2.setRNGSeed(0)
    _, _, centres = cv2.kmeans(samples, min(clusters, len(samples)), None, criteria, 2, cv2.KMEANS_PP_CENTERS)
    return centres


def _touches_all_borders(mask: np.ndarray) -> bool:
    return bool(mask[0].any() and mask[-1].any() and mask[:, 0].any() and mask[:, -1].any())


def _clean(mask: np.ndarray) -> np.ndarray:
    """Open away specks, keep the object-sized components, fill holes under 1 % of them."""
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    mask = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, kernel) > 0
    objects = split_objects(mask)
    if not objects:
        return np.zeros_like(mask)
    mask = np.logical_or.reduce(objects)
    _, labels, stats, _ = cv2.connectedComponentsWithStats((~mask).astype(np.uint8), connectivity=4)
    edge_labels = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    small = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] < MAX_FILLED_HOLE * mask.sum())
    return mask | np.isin(labels, np.setdiff1d(small, edge_labels))


#: Shape-prior refinement: how far (fractions of the template's long side) beyond the
#: placed template's outline the object may reach; beyond lies definite background. A
#: template fitted to a mask that lost its wings is too small, so a wide reach is tried too.
PRIOR_REACHES = (0.1, 0.25)
#: Depth, as a fraction of the template's long side, of the template's core that is sure
#: foreground where the first mask agrees.
PRIOR_CORE = 0.04
#: A refined mask replaces the first when a template explains it better by this IoU.
PRIOR_MIN_GAIN = 0.02
#: A colour within this multiple of the border's median distance to its own colour
#: clusters is background-like; a shape-prior cut may not add mostly such pixels.
BACKGROUND_LIKE_DISTANCE = 1.0
#: Share of the pixels the first mask and a template agree on that a shape-prior cut must keep.
PRIOR_KEPT = 0.9
#: Long side of the image the shape-prior candidates are cut on (thin wings need the
#: first pass's size); only the winner's edge is refined at full resolution.
PRIOR_SIZE = GRABCUT_SIZE
#: GrabCut iterations per shape-prior candidate.
PRIOR_ITERATIONS = 5


def refine_with_shape_prior(image: np.ndarray, mask: np.ndarray, renders: Mapping[str, TemplateRenders],
                            agreement: Mapping[str, Agreement], max_angle: float = np.pi,
                            exclude: np.ndarray | None = None, past_box: bool = False) -> np.ndarray:
    """Re-segment with the templates placed on the first mask as shape priors; ``mask`` when none helps.

    Clutter that fools the first pass (a blob of the object's colour touching a wing, a
    wing lost against a background of nearly its colour) is judged again by GrabCut
    seeded from each subtype's template where the classifier placed it (``agreement``,
    :func:`frontal3d.stages.classify.silhouette_agreement` of ``mask``): probable
    foreground inside the template, sure foreground in its core where ``mask`` agrees,
    sure background beyond a reach of its outline (:data:`PRIOR_REACHES`) and in
    ``exclude`` (occluders). Every subtype is tried: a mask that lost its wings fits
    the wrong subtype best. The template only seeds; colour decides the edge.

    A candidate is judged as the classifier judges the first mask: its silhouette
    agreement with its template, re-fitted (``past_box`` as in that function). The best replaces ``mask`` only when it
    beats the first mask's best agreement by :data:`PRIOR_MIN_GAIN`; the template is
    a generic shape, so a colour cut that merely hugs it (or takes clutter in its
    reach) must make the object more template-like, not just different. An already
    good mask (a plain background) is thus returned unchanged.
    """
    mask = np.asarray(mask, dtype=bool)
    if not mask.any() or not agreement:
        return mask
    rgb = np.ascontiguousarray(image[..., :3], dtype=np.uint8)
    height, width = mask.shape
    scale = min(1.0, PRIOR_SIZE / max(height, width))
    size = (max(1, round(width * scale)), max(1, round(height * scale)))

    def shrink(array: np.ndarray) -> np.ndarray:
        return cv2.resize(array.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0

    small = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
    first = shrink(mask)
    background_like = _background_like(small)
    excluded = None if exclude is None else shrink(np.asarray(exclude, dtype=bool))
    best, best_score = None, max(found.iou for found in agreement.values()) + PRIOR_MIN_GAIN
    for subtype, found in agreement.items():
        prior = shrink(warp_mask(renders[subtype].mask, found.similarity, mask.shape))
        if not prior.any():
            continue
        for reach in PRIOR_REACHES:
            candidate = _segment_with_prior(small, first, prior, excluded, reach)
            if candidate is None or not _consistent(candidate, first, prior, background_like):
                continue
            # The IoU of the re-fitted template does not depend on the mask's resolution.
            score = silhouette_agreement(candidate, {subtype: renders[subtype]}, max_angle, past_box=past_box)[subtype].iou
            if score > best_score:
                best, best_score = candidate, score
    if best is None:
        return mask
    refined = _refine_edge(rgb, best)
    if exclude is not None:
        refined &= ~np.asarray(exclude, dtype=bool)
    return refined


def _segment_with_prior(small: np.ndarray, first: np.ndarray, prior: np.ndarray, exclude: np.ndarray | None, reach_fraction: float) -> np.ndarray | None:
    """GrabCut seeded from one placed template (see :func:`refine_with_shape_prior`), or None."""
    extent = mask_extent(prior)
    near = _dilated(prior, max(2, round(reach_fraction * extent)))
    core = (cv2.erode(prior.astype(np.uint8), disc(max(1, round(PRIOR_CORE * extent)))) > 0) & first
    labels = np.full(prior.shape, cv2.GC_PR_BGD, np.uint8)
    labels[prior | (first & near)] = cv2.GC_PR_FGD
    labels[core] = cv2.GC_FGD
    labels[~near] = cv2.GC_BGD
    if exclude is not None:
        labels[exclude] = cv2.GC_BGD
    if not (labels == cv2.GC_BGD).any() or not np.isin(labels, (cv2.GC_FGD, cv2.GC_PR_FGD)).any():
        return None
    _grabcut(small, labels, PRIOR_ITERATIONS)
    found = _clean(_foreground(labels))
    return found if found.any() else None


def _consistent(candidate: np.ndarray, first: np.ndarray, prior: np.ndarray, background_like: np.ndarray) -> bool:
    """Whether a shape-prior cut corrects the first mask rather than replacing it.

    It must keep what the first mask and its template agree on (a cut that lost the
    fuselage found something else), hug its template at least as well as the first mask
    does and not spread to more image borders (a cut that floods a background of the
    object's colour does both, however well some other placement would explain the
    flood), and what it adds must not look like the image border (a template placed a
    little off pulls in the background between a wing and the tail).
    """
    agreed = first & prior
    kept = np.count_nonzero(candidate & agreed) >= PRIOR_KEPT * np.count_nonzero(agreed)
    spread = _borders_touched(candidate) > _borders_touched(first)
    added = candidate & ~first
    adds_background = added.any() and background_like[added].mean() > 0.5
    return kept and _iou(candidate, prior) >= _iou(first, prior) and not spread and not adds_background


def _borders_touched(mask: np.ndarray) -> int:
    return int(mask[0].any()) + int(mask[-1].any()) + int(mask[:, 0].any()) + int(mask[:, -1].any())


def _background_like(rgb: np.ndarray) -> np.ndarray:
    """Pixels whose colour is as close to the image border's colours as most border pixels are."""
    lab = cv2.GaussianBlur(cv2.cvtColor(rgb, cv2.COLOR_RGB2LAB).astype(np.float32), (0, 0), 1.5)
    border = _border_mask(rgb.shape[:2])
    distance = distance_to_colours(lab, lab[border])
    typical = max(1.0, float(np.median(distance[border])))
    return distance <= BACKGROUND_LIKE_DISTANCE * typical


def _dilated(mask: np.ndarray, radius: int) -> np.ndarray:
    return cv2.dilate(mask.astype(np.uint8), disc(radius)) > 0


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.count_nonzero(a & b) / max(np.count_nonzero(a | b), 1))
