"""Occlusions: things in front of the object, and the silhouette and regions behind them.

Paper section 3.2.3 (Figs. 5-7). Occluder masks come from the ``frontal3d_occluders``
hook (every plugin's masks are OR-ed; the core's default finds people's arms and
hands) and from the user's ``--occluder-mask``. The object's boundary where an
occluder covers it is replaced by the matching part of the aligned template's
contour, bent to meet the visible boundary at both ends; the region map is then
completed over the rebuilt mask so the texture stage can inpaint each region from itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from frontal3d.masks import disc, inset, mask_extent, opened, pieces_touching, within
from frontal3d.stages.align import Similarity, warp_mask
from frontal3d.stages.boundary import default_k, match_contours, trace_contour
from frontal3d.stages.classify import Agreement, ClassifierContext, silhouette_agreement
from frontal3d.stages.mirror_outline import MirrorLine, find_mirror_line, mirror_filled, reflected
from frontal3d.stages.regions import reconstruct_region_map
from frontal3d.stages.segment import distance_to_colours
from scipy.ndimage import binary_fill_holes

#: Reach of an occluder, as a fraction of the working image's long side (the object's size,
#: for :func:`hidden_by` on the full image): template pixels this close to an occluder may
#: join the silhouette, and object boundary this close to one counts as occluded (its true
#: course is unknown there).
OCCLUDER_REACH = 0.02
#: Occluded boundary runs separated by fewer visible points than this are one part.
MIN_VISIBLE_GAP = 4
#: A detected occluder's pixels on the object vote, by colour, whether they show the occluder
#: or the object; the votes are averaged over this fraction of the object's size.
COLOUR_VOTE_WINDOW = 0.03
#: With fewer of its pixels seen off the object the occluder's colours are unknown: all its
#: pixels on the object stay occluded (a close-up hand lying wholly on the guitar).
MIN_COLOUR_REFERENCE = 50
#: People's pixels judged in front of the object must hide a stretch at least twice this
#: fraction of the template's size across: a person behind the object, next to a template
#: wider than the object, claims only a band along the object's outline.
IN_FRONT_DEPTH = 0.04
#: Each piece of what people hide must also cover at least this share of the template's
#: size squared (a tenth of a guitar's area): a template placed a little wider or off to
#: one side of the object, with a person behind, still claims a short thick piece by a horn.
IN_FRONT_MIN_AREA = 0.023


@dataclass
class BoundaryPart:
    """One rebuilt stretch of the silhouette: its visible end points (x, y) and lengths in pixels."""

    start: tuple[float, float]
    end: tuple[float, float]
    occluded_length: int
    rebuilt_length: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "start": [round(v, 1) for v in self.start],
            "end": [round(v, 1) for v in self.end],
            "occluded_length_px": self.occluded_length,
            "rebuilt_length_px": round(self.rebuilt_length, 1),
        }


@dataclass
class RebuiltSilhouette:
    """The object's mask with occluded parts restored, which pixels were occluded, and the rebuilt boundary parts."""

    mask: np.ndarray
    occluded: np.ndarray
    original_area: int
    boundary_parts: list[BoundaryPart] = field(default_factory=list)
    mirror: MirrorLine | None = None

    def summary(self) -> dict[str, Any]:
        area = int(self.mask.sum())
        summary = {
            "occluded_fraction": round(float(self.occluded.sum()) / max(area, 1), 4),
            "restored_pixels": int(area - self.original_area),
            "rebuilt_boundary_parts": [part.to_dict() for part in self.boundary_parts],
        }
        if self.mirror is not None:
            summary["mirror"] = {**self.mirror.to_dict(), "used": self.mirror.usable}
        return summary


def find_occluders(plugins: Any, image: np.ndarray, object_mask: np.ndarray, settings: dict[str, Any], user_mask: np.ndarray | None,
                   notes: dict[str, Any] | None = None) -> np.ndarray | None:
    """OR of every occluder plugin's mask and the user's; None when nothing occludes.

    ``notes`` (the report's data) gets how many detected pixels on the object were judged
    to show the object (:func:`shown_in_front`), so a user can see why an arm was not rebuilt."""
    found = [np.asarray(m, dtype=bool) for m in plugins.hook.frontal3d_occluders(image=image, object_mask=object_mask, settings=settings) if m is not None]
    if found:
        detected = np.logical_or.reduce(found)
        found = [shown_in_front(detected, image, object_mask)]
        if notes is not None:
            notes["detected_occluder_pixels_seen_as_object"] = int(np.count_nonzero(detected & ~found[0]))
    if user_mask is not None:
        found.append(user_mask)
    if not found:
        return None
    combined = np.logical_or.reduce(found)
    return combined if combined.any() else None


def shown_in_front(detected: np.ndarray, image: np.ndarray, object_mask: np.ndarray) -> np.ndarray:
    """The detected occluder without its pixels on the object that show the object.

    A pose model draws a guitarist's arm across the guitar whether the arm is in front or
    behind it, and the person segmenter counts a held guitar as the person. Where the
    occluder lies on the object, each pixel is compared with the occluder's own colours
    (its pixels off the object) and the object's (its pixels away from the occluder); the
    pixels the object's colours explain better, by a vote averaged over COLOUR_VOTE_WINDOW,
    are the object seen. The user's occluder mask is not judged (see :func:`find_occluders`).
    """
    detected = np.asarray(detected, dtype=bool)
    object_mask = np.asarray(object_mask, dtype=bool)
    on_object = detected & object_mask
    if not on_object.any() or np.count_nonzero(detected & ~object_mask) < MIN_COLOUR_REFERENCE:
        return detected
    window = max(3, round(COLOUR_VOTE_WINDOW * mask_extent(object_mask)))
    grown = within(detected, max(1, window // 2))
    seen_object = object_mask & ~grown
    if np.count_nonzero(seen_object) < MIN_COLOUR_REFERENCE:
        return detected
    lab = cv2.cvtColor(np.ascontiguousarray(image[..., :3], dtype=np.uint8), cv2.COLOR_RGB2Lab).astype(np.float32)
    pixels = lab[on_object][:, None]
    occluder_like = np.zeros(detected.shape, np.float32)
    occluder_like[on_object] = distance_to_colours(pixels, lab[detected & ~object_mask])[:, 0] < distance_to_colours(pixels, lab[seen_object])[:, 0]
    votes = cv2.blur(occluder_like, (window, window)) / np.maximum(cv2.blur(on_object.astype(np.float32), (window, window)), 1e-6)
    return (detected & ~object_mask) | (on_object & (votes >= 0.5))


def hidden_by(occluders: np.ndarray, object_mask: np.ndarray) -> np.ndarray:
    """Pixels whose membership in the silhouette the occluders leave unknown: the occluders
    grown by OCCLUDER_REACH of the object's size (an arm's soft edge hides the outline too)."""
    return within(occluders, max(1, round(OCCLUDER_REACH * mask_extent(object_mask))))


def in_front(people: np.ndarray, object_mask: np.ndarray, aligned_template_mask: np.ndarray, mirror_axis: float | None = None) -> np.ndarray:
    """The pixels by which people hide the object, found with the aligned template.

    Where the template expects the object (deeper than OCCLUDER_REACH inside it) but the
    object is not seen, a person there, or a gap touching a person (dark sleeves and a
    held camera the person segmenter loses over the object), stands in front of it. Their
    surroundings up to twice that reach, off the object, are added where they cross the
    outline. A body behind the object meets the template only along its edge (the
    alignment's error), so it is left out and the outline it borders stays the one seen;
    so is a body behind an object slimmer than the template (a bass against an electric
    template), seen only in a band along the outline: what stands in front must hide a
    stretch at least twice IN_FRONT_DEPTH across, in pieces of at least IN_FRONT_MIN_AREA.
    The template's own slender parts (a neck), which no depth test can pass, are in front
    where a person over them joins such a piece.
    People's pixels on the object (a held guitar the segmenter counts as the person) stay object.
    With ``mirror_axis`` (the placed template's mirror line) the object's own mirror image
    also expects the object, where it matches the seen object better than the template
    (:mod:`~frontal3d.stages.mirror_outline`): a bite the template's cutaway happens to fit.
    """
    people = np.asarray(people, dtype=bool)
    off_object = ~np.asarray(object_mask, dtype=bool)
    template = np.asarray(aligned_template_mask, dtype=bool)
    if not template.any():
        return np.zeros_like(people)
    size = mask_extent(template)
    if mirror_axis is not None and people.any():
        line = find_mirror_line(~off_object, hidden_by(people, ~off_object), template, mirror_axis)
        if line is not None and line.usable:
            template = template | reflected(~off_object, line.matrix)
    radius = max(1, round(OCCLUDER_REACH * size))
    unseen = off_object & inset(template, radius)
    _count, pieces = cv2.connectedComponents(unseen.astype(np.uint8))
    # The person segmenter's mask spills a few pixels over the object's edge (and takes in a
    # held object): only the person away from the object can vouch for a gap.
    away = people & ~within(~off_object, radius)
    near_people = cv2.dilate(away.astype(np.uint8), disc(1)) > 0
    touched = np.unique(pieces[near_people & unseen])
    inside = np.isin(pieces, touched[touched > 0])
    if not inside.any():
        return np.zeros_like(people)
    claimed = (people | inside) & off_object & within(inside, 2 * radius)
    depth = max(1, round(IN_FRONT_DEPTH * size))
    kept = claimed & within(opened(claimed, depth), depth)
    count, kept_pieces, stats, _centroids = cv2.connectedComponentsWithStats(kept.astype(np.uint8), connectivity=8)
    large = 1 + np.flatnonzero(stats[1:count, cv2.CC_STAT_AREA] >= IN_FRONT_MIN_AREA * size * size)
    found = np.isin(kept_pieces, large)
    # A person over a neck covers it on one side only next to the body: without this the
    # rebuilt outline stops at a gap there and the neck is lost.
    slender = template & ~opened(template, depth) & off_object & (people | inside)
    return found | _pieces_touching(slender, found)


@dataclass
class VisibleAgreementContext(ClassifierContext):
    """A classifier context whose silhouette agreement is scored only where the object is
    seen: ``hidden`` pixels (see :func:`hidden_by`) must not vote, or an arm across a
    classical guitar's waist, filled in as body, makes its outline look electric.

    ``view_hidden`` is hidden from the frontal gate only: people touching the object whose
    pixels may be in front of it or behind it. Whether the outline there is the object's
    is unknown, which is no evidence against a front view; the subtype still sees them, as a
    guitarist's body behind a small electric body must not let a large classical body fit.

    For the subtype each template is also placed with ``view_hidden`` left out of the
    placement (not of the score), and the placement whose seen IoU is higher stands: a
    person's edge next to the outline can trap one subtype's search (an astronaut beside a
    classical body pulled its template off the lower bout, and the electric one won). Both
    subtypes get the same two tries; the gate and the alignment keep the first placement.
    """

    hidden: np.ndarray | None = None
    view_hidden: np.ndarray | None = None
    _view_agreement: dict[str, Agreement] | None = field(default=None, repr=False)
    _subtype_agreement: dict[str, Agreement] | None = field(default=None, repr=False)

    def agreement(self) -> dict[str, Agreement]:
        if self._agreement is None:
            placed = silhouette_agreement(self.object_mask, self.renders, self.max_angle(), hidden=self.hidden)
            self._agreement = self._seen(placed, self.hidden)
        return self._agreement

    def view_agreement(self) -> dict[str, Agreement]:
        if self.view_hidden is None:
            return self.agreement()
        if self._view_agreement is None:
            self._view_agreement = self._seen(self.agreement(), self.view_hidden_pixels())
        return self._view_agreement

    def subtype_agreement(self) -> dict[str, Agreement]:
        if self._subtype_agreement is None:
            placed, freed = self.agreement(), self.view_hidden_pixels()
            if self.view_hidden is not None and (self.hidden is None or (freed & ~self.hidden).any()):
                free = self._seen(silhouette_agreement(self.object_mask, self.renders, self.max_angle(), hidden=freed), self.hidden)
                placed = {subtype: max(found, free[subtype], key=lambda agreement: agreement.iou) for subtype, found in placed.items()}
            self._subtype_agreement = placed
        return self._subtype_agreement

    def view_hidden_pixels(self) -> np.ndarray | None:
        if self.view_hidden is None or self.hidden is None:
            return self.hidden if self.view_hidden is None else self.view_hidden
        return self.view_hidden | self.hidden

    def outline_partly_hidden(self) -> bool:
        return any(mask is not None and mask.any() for mask in (self.hidden, self.view_hidden))

    def _seen(self, placed: dict[str, Agreement], hidden: np.ndarray | None) -> dict[str, Agreement]:
        return {subtype: Agreement(iou=seen_iou(self.renders[subtype].mask, found.similarity, self.object_mask, hidden), similarity=found.similarity)
                for subtype, found in placed.items()}


def seen_iou(template_mask: np.ndarray, similarity: Similarity, object_mask: np.ndarray, hidden: np.ndarray | None) -> float:
    """IoU of the placed template and the object, counted outside the ``hidden`` pixels."""
    placed = warp_mask(template_mask, similarity, object_mask.shape)
    seen = np.ones_like(object_mask) if hidden is None else ~hidden
    return float(np.count_nonzero(placed & object_mask & seen) / max(np.count_nonzero((placed | object_mask) & seen), 1))


def rebuild_silhouette(object_mask: np.ndarray, occluders: np.ndarray, aligned_template_mask: np.ndarray, *, k: int | None = None,
                       mirror_axis: float | None = None) -> RebuiltSilhouette:
    """Restore the silhouette where occluders cover it, using the aligned template.

    1. Fill: the object plus the aligned template near the occluders, closed and with
       holes filled, so a bite or a cut through the object becomes one outline.
    2. The outline's points within reach of an occluder form occluded parts; the
       outline is matched to the template's (eq. 1-2, jump bound ``k``, default
       :func:`default_k`), and each part is replaced by the template stretch matched
       between its two visible end points, moved by the similarity that sends the
       template's end points onto them (the paper's procedure).
    3. The closed outline is filled and the visible object added back.
    4. With ``mirror_axis`` (the placed template's mirror line, radians from image-up), the
       object's own mirror image replaces the template's guess wherever it is seen, when
       the seen object matches its mirror image better than the template
       (:mod:`~frontal3d.stages.mirror_outline`).
    The occluded pixels (to inpaint) are the rebuilt mask's pixels under the occluders or restored.
    """
    object_mask = np.asarray(object_mask, dtype=bool)
    occluders = np.asarray(occluders, dtype=bool)
    aligned_template_mask = np.asarray(aligned_template_mask, dtype=bool)
    original_area = int(object_mask.sum())
    kernel = disc(max(1, round(OCCLUDER_REACH * max(object_mask.shape))))
    reach = cv2.dilate(occluders.astype(np.uint8), kernel) > 0
    if not (reach & object_mask).any():
        return RebuiltSilhouette(object_mask, np.zeros_like(object_mask), original_area)

    visible = object_mask & ~occluders
    filled = _filled(visible, reach & aligned_template_mask, kernel, reach)
    contour = trace_contour(filled)
    parts = _occluded_runs(_values_at(reach, contour))
    rebuilt_parts: list[BoundaryPart] = []
    if parts and aligned_template_mask.any():
        template_contour = trace_contour(aligned_template_mask)
        omega = match_contours(contour, template_contour, k or default_k(max(object_mask.shape)))
        contour, rebuilt_parts = _replace_parts(contour, template_contour, omega, parts)
        outline = np.zeros(object_mask.shape, np.uint8)
        cv2.fillPoly(outline, [np.round(contour).astype(np.int32)], 1)
        filled = binary_fill_holes((outline > 0) | visible)
    mirror = find_mirror_line(visible, reach, aligned_template_mask, mirror_axis) if mirror_axis is not None else None
    if mirror is not None and mirror.usable:
        filled = mirror_filled(filled, visible, reach, occluders, mirror)
    # Inpainted: every restored pixel (what the image shows there is not the object) and the
    # occluders with one pixel of slack (their anti-aliased edge).
    occluded = filled & ((cv2.dilate(occluders.astype(np.uint8), disc(1)) > 0) | ~object_mask)
    return RebuiltSilhouette(filled, occluded, original_area, rebuilt_parts, mirror)


def occluded_at_full_resolution(upsampled: np.ndarray, rebuilt_mask: np.ndarray, seen_object: np.ndarray,
                                occluders: np.ndarray | None) -> np.ndarray:
    """The pixels of the full-resolution rebuilt mask to inpaint.

    ``upsampled`` is the working grid's occluded mask scaled up, which misses what the
    working grid could not resolve: an occluder's edge, a finger one working pixel wide,
    the border pixels the coarse outline adds. Added here, at full resolution: every
    pixel of ``rebuilt_mask`` the ``seen_object`` mask leaves out (whatever shows there is
    not the object) and the full-resolution ``occluders`` on it with one pixel of slack
    (their anti-aliased edge), so no occluder pixel is kept or copied as a source.
    """
    rebuilt_mask = np.asarray(rebuilt_mask, dtype=bool)
    occluded = np.asarray(upsampled, dtype=bool) | ~np.asarray(seen_object, dtype=bool)
    if occluders is not None:
        occluded |= cv2.dilate(np.asarray(occluders, dtype=np.uint8), disc(1)) > 0
    return rebuilt_mask & occluded


def rebuild_regions(regions: np.ndarray, object_mask: np.ndarray, occluded: np.ndarray, n_regions: int) -> np.ndarray:
    """Give every pixel of the (rebuilt) mask a region, filling occluded ones from neighbours."""
    needs_fill = object_mask & ((regions < 0) | occluded)
    return reconstruct_region_map(np.where(object_mask, regions, -1), object_mask, needs_fill)


def _filled(visible: np.ndarray, template_near_occluders: np.ndarray, kernel: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Visible object plus the template pieces under occluders that touch it, closed within the
    occluders' reach (the outline elsewhere, a headstock's tuner gaps, is seen) and hole-free (paper Fig. 5)."""
    joined = visible | _pieces_touching(template_near_occluders, visible)
    closed = cv2.morphologyEx(joined.astype(np.uint8), cv2.MORPH_CLOSE, kernel) > 0
    return binary_fill_holes(joined | (closed & reach))


def _pieces_touching(mask: np.ndarray, other: np.ndarray) -> np.ndarray:
    """The pieces of ``mask`` that touch ``other`` (lie within one pixel of it)."""
    return pieces_touching(mask, other, disc(1))


def _values_at(mask: np.ndarray, points: np.ndarray) -> np.ndarray:
    cols, rows = np.round(points).astype(np.intp).T
    return mask[rows, cols]


def _occluded_runs(occluded: np.ndarray) -> list[tuple[int, int]]:
    """Cyclic runs [first, last] of occluded contour points, gaps shorter than MIN_VISIBLE_GAP bridged.

    A run needs a visible point on each side (its end points); a fully occluded outline has none.
    """
    m = len(occluded)
    if occluded.all() or not occluded.any():
        return []
    shift = int(np.argmin(occluded))  # start the walk on a visible point, so no run wraps
    flags = np.roll(occluded, -shift).astype(np.int8)
    edges = np.diff(np.concatenate([[0], flags, [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    runs: list[list[int]] = []
    for start, stop in zip(starts, stops):
        if runs and start - runs[-1][1] < MIN_VISIBLE_GAP:
            runs[-1][1] = stop
        else:
            runs.append([start, stop])
    if len(runs) > 1 and (m - runs[-1][1]) + runs[0][0] < MIN_VISIBLE_GAP:
        runs[0][0] = runs.pop()[0] - m
    return [((start + shift) % m, (stop - 1 + shift) % m) for start, stop in runs]


def _replace_parts(contour: np.ndarray, template_contour: np.ndarray, omega: np.ndarray,
                   parts: list[tuple[int, int]]) -> tuple[np.ndarray, list[BoundaryPart]]:
    """The outline with each occluded part swapped for its matched, end-point-fitted template stretch."""
    m, n = len(contour), len(template_contour)
    pieces, rebuilt = [], []
    visible_from = (parts[-1][1] + 1) % m
    for first, last in parts:
        before, after = (first - 1) % m, (last + 1) % m
        pieces.append(contour[_cyclic_range(visible_from, before, m)])
        start_point, end_point = contour[before], contour[after]
        stretch = template_contour[_cyclic_range(omega[before], omega[after], n)]
        fitted = _fit_between(stretch, start_point, end_point)
        pieces.append(fitted[1:-1])
        rebuilt.append(BoundaryPart(
            start=(float(start_point[0]), float(start_point[1])),
            end=(float(end_point[0]), float(end_point[1])),
            occluded_length=int((last - first) % m + 1),
            rebuilt_length=float(np.linalg.norm(np.diff(fitted, axis=0), axis=1).sum()),
        ))
        visible_from = after
    return np.concatenate(pieces), rebuilt


def _cyclic_range(first: int, last: int, length: int) -> np.ndarray:
    """Indices first, first + 1, ..., last, wrapping around a cycle of ``length``."""
    return (first + np.arange((last - first) % length + 1)) % length


def _fit_between(stretch: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """The similarity sending the stretch's end points onto ``start`` and ``end``, applied to it.

    A stretch whose ends coincide (the match collapsed) is only translated; the
    straight gap to ``end`` then closes when the outline is filled.
    """
    z = stretch[:, 0] + 1j * stretch[:, 1]
    a, b = z[0], z[-1]
    p, q = complex(*start), complex(*end)
    moved = p + (z - a) * ((q - p) / (b - a)) if abs(b - a) >= 1.0 else z + (p - a)
    return np.stack([moved.real, moved.imag], axis=1)


#: Tints of :func:`occlusion_sheet` (RGB): what stands in front, people judged behind, the
#: placed template's outline and the rebuilt part of the silhouette.
IN_FRONT_TINT = (230, 40, 40)
BEHIND_TINT = (40, 110, 240)
TEMPLATE_OUTLINE = (255, 215, 0)
REBUILT_COLOUR = (230, 40, 40)


def occlusion_sheet(rgb: np.ndarray, seen: np.ndarray, people: np.ndarray, occluders: np.ndarray,
                    template: np.ndarray, rebuilt: np.ndarray, regions_picture: np.ndarray, occluded: np.ndarray) -> np.ndarray:
    """Four labelled panels on the working grid, as the paper's Figs. 5-7, for ``-v``.

    1. Who stands where: the occluders in front of the object (red: arms and hands found, the
       people judged in front, the user's mask) and the people judged behind (blue).
    2. The object as seen, the rest of the photo dimmed, with the placed template's outline.
    3. The rebuilt silhouette: seen pixels white, the pixels rebuilt under the occluders red,
       with the same template outline.
    4. The rebuilt region map (``regions_picture``, one colour per region), the ``occluded``
       pixels the texture inpaints from their region paled.

    When a person is taken for in front or behind the wrong way, or a bite is left in the
    outline, these show which step went wrong.
    """
    rgb = np.ascontiguousarray(rgb[..., :3], dtype=np.uint8)
    seen, people, occluders, rebuilt, occluded = (np.asarray(a, dtype=bool) for a in (seen, people, occluders, rebuilt, occluded))
    who = _tinted(_tinted(rgb, people & ~occluders, BEHIND_TINT), occluders, IN_FRONT_TINT)
    as_seen = np.where(seen[..., None], rgb, (rgb * 0.35).astype(np.uint8))
    silhouette = np.zeros_like(rgb)
    silhouette[rebuilt & seen] = 255
    silhouette[rebuilt & ~seen] = REBUILT_COLOUR
    regions = _tinted(np.ascontiguousarray(regions_picture, dtype=np.uint8), occluded, (255, 255, 255))
    panels = [(who, "in front (red), behind (blue)"), (as_seen, "seen, template outline"), (silhouette, "rebuilt (red)"),
              (regions, "regions, inpainted (pale)")]
    outline, _ = cv2.findContours(np.asarray(template, np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    for panel, _label in panels[1:3]:
        cv2.drawContours(panel, outline, -1, TEMPLATE_OUTLINE, 1)
    for panel, label in panels:
        cv2.putText(panel, label, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    return np.concatenate([panel for panel, _ in panels], axis=1)


def _tinted(rgb: np.ndarray, where: np.ndarray, colour: tuple[int, int, int]) -> np.ndarray:
    """``rgb`` with ``where`` blended half-way towards ``colour``."""
    out = rgb.copy()
    out[where] = ((rgb[where].astype(np.uint16) + np.array(colour, np.uint16)) // 2).astype(np.uint8)
    return out
