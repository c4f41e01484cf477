"""Runs the stages in order and owns the report.

One reconstruction is a straight line of stages (docs/architecture.md): each stage
is a function in ``frontal3d.stages``, takes plain data and returns plain data; this
module only sequences them, asks the plugins where a hook decides, times every
stage and collects the decisions and warnings into ``report.json``.
"""

from __future__ import annotations

import copy
import functools
import logging
import resource
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, NamedTuple

import cv2
import numpy as np
from scipy.ndimage import binary_fill_holes

from frontal3d import learned_dense
from frontal3d import occluders as people_detector
from frontal3d.errors import ConfigError, InputError, NoObjectError, NotFrontalError, TemplateError, UnknownFamilyError
from frontal3d.family import Family, Template
from frontal3d.imageio import as_rgb, mask_from_array, read_image, read_mask
from frontal3d.masks import pieces_touching, within
from frontal3d.plugins import Plugins
from frontal3d.render import TemplateRenders, load_or_render
from frontal3d.stages import align, boundary, classify, mesh, mirror_repair, occlusion, segment, texture, warp
from frontal3d.stages.export import debug_picture, export_all
from frontal3d.stages.mirror_symmetry import template_mirror

log = logging.getLogger("frontal3d")

#: Margin, as a fraction of the object's bounding box, kept around the crop the
#: shape stages work on (room for the template to overhang before warping).
CROP_MARGIN = 0.08
#: How far beyond the object's bounding box (a fraction of its size) a person in front
#: may hide its outline: the crop covers the people touching the object that far.
PEOPLE_REACH = 0.25
#: How much longer than the shortest way between a piece a person cut off and the object a
#: path through the gap may be and still lie under the person (pipeline._gaps_to).
GAP_SLACK = 1.2
#: The outline next to people stops voting on the template placement that judges who stands
#: in front (see _people_in_front). The segmenter alone is as sure of some soft blobs beside
#: objects, whose freed outline can let the placement drift until the gate calls a clean
#: object turned: with only its word for a person, an object the gate turns down is judged
#: again with that outline voting. With a pose or a face the verdict stands.
TRUSTED_PEOPLE_EVIDENCE = ("pose", "face")
#: The template judging who stands in front is also placed with the outline next to people
#: voting; when the two placements turn more than this apart (degrees), one has been dragged
#: across people, and the one whose long axis lies along the object's stands (_people_in_front).
MAX_FREED_TURN_DEG = 20.0
#: Unoccluded, the alignment's mutual information may give up a little outline IoU for the grey
#: image's agreement (the shared renders: up to 0.045, and the shapes are better for it). A
#: placement behind the classifier's, from masks alone, by more than this has gone astray: on a
#: sunburst guitar photo, 0.73 against 0.82, and the model 13 % shorter than from its re-encoding (0.83).
MI_OUTLINE_SLACK = 0.05
#: A hole in the segmenters' mask that the placed template mostly covers (TEMPLATE_COVERED_HOLE of
#: its pixels) and under MAX_FILLED_HOLE of the mask's area is filled: a chrome hub or a window the
#: segmenter took for the white background behind it. Larger ones stay (a glassless window, a
#: box wing), as do the holes a template has itself and every hole in a mask the user gave
#: (the ``fill_holes`` setting turns it off).
MAX_FILLED_HOLE = 0.05
TEMPLATE_COVERED_HOLE = 0.5


@dataclass
class Report:
    """What happened, for report.json: decisions, per-stage seconds, warnings."""

    data: dict[str, Any] = field(default_factory=lambda: {"stages": {}, "peak_memory_mb": {}, "warnings": []})

    @contextmanager
    def stage(self, name: str, progress: Callable[[str], None] | None = None) -> Iterator[None]:
        """Time a stage and note the process's peak memory after it."""
        if progress:
            progress(name)
        log.info("stage %s", name)
        start = time.perf_counter()
        yield
        self.data["stages"][name] = round(time.perf_counter() - start, 4)
        self.data["peak_memory_mb"][name] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)

    def warn(self, message: str) -> None:
        """Record a warning in the report (the CLI prints the report's warnings; -v logs them as they happen)."""
        log.info("warning: %s", message)
        self.data["warnings"].append(message)


@dataclass
class Reconstruction:
    """The result of one reconstruction: the textured mesh, its maps and the report."""

    textured: texture.TexturedMesh
    landmarks: dict[str, np.ndarray]
    report: dict[str, Any]
    maps: dict[str, np.ndarray]

    @property
    def mesh(self):
        """The watertight geometry (the textured mesh splits vertices along UV seams)."""
        return self.textured.watertight_mesh

    def save(self, out_dir: Path, debug: bool = False) -> dict[str, Path]:
        """Write model.glb, model.obj/.mtl, textures, preview.png and report.json into ``out_dir``."""
        debug_maps = self.maps if debug else {}
        return export_all(Path(out_dir), self.textured, self.landmarks, self.report, debug_maps=debug_maps)


@dataclass
class _Crop:
    """The object's crop of the full image and its working-resolution copy."""

    x0: int
    y0: int
    width: int
    height: int
    scale: float  # working pixels per full-resolution pixel

    @property
    def working_shape(self) -> tuple[int, int]:
        return max(1, round(self.height * self.scale)), max(1, round(self.width * self.scale))


def reconstruct(
    image: np.ndarray | str | Path,
    family: str | None = None,
    *,
    mask: np.ndarray | str | Path | None = None,
    occluder_mask: np.ndarray | str | Path | None = None,
    subtype: str | None = None,
    plugins: Plugins | None = None,
    progress: Callable[[str], None] | None = None,
    **settings: Any,
) -> Reconstruction:
    """Reconstruct a textured, watertight mesh from one frontal photo.

    ``family`` is a family name or None/"auto" to let the classifier chain pick;
    ``mask`` and ``occluder_mask`` are optional user masks (arrays or paths);
    ``subtype`` skips the subtype classifier; ``settings`` override the family's
    settings (plugins.toml keys). Of several separate objects, the largest the classifier
    chain accepts is reconstructed (:func:`reconstruct_all`: each). Raises a
    :class:`frontal3d.errors.Frontal3DError` with a one-line reason on bad input or a
    rejected view.
    """
    return _reconstruct_objects(image, family, mask, occluder_mask, subtype, plugins, progress, settings, every=False)[0]


def reconstruct_all(
    image: np.ndarray | str | Path,
    family: str | None = None,
    *,
    mask: np.ndarray | str | Path | None = None,
    occluder_mask: np.ndarray | str | Path | None = None,
    subtype: str | None = None,
    plugins: Plugins | None = None,
    progress: Callable[[str], None] | None = None,
    **settings: Any,
) -> list[Reconstruction]:
    """:func:`reconstruct` for each separate object of the photo the classifier chain accepts,
    largest first (with ``family`` auto: of the family that fits the first best). Raises as
    :func:`reconstruct` when it accepts none."""
    return _reconstruct_objects(image, family, mask, occluder_mask, subtype, plugins, progress, settings, every=True)


@dataclass
class _Accepted:
    """One object the classifier chain accepted, with what shape reconstruction needs of it."""

    rank: int  # among the separate objects, largest first
    object_mask: np.ndarray
    probable: np.ndarray
    occluders: np.ndarray | None
    people_near: np.ndarray
    decisions: list[classify.Decision]
    subtype: str
    renders_by_subtype: dict[str, TemplateRenders]
    context: classify.ClassifierContext
    report: Report

    @property
    def frontal_confidence(self) -> float:
        return max((d.confidence for d in self.decisions if d.name == "frontal"), default=0.0)


def _reconstruct_objects(image: np.ndarray | str | Path, family: str | None, mask: np.ndarray | str | Path | None,
                         occluder_mask: np.ndarray | str | Path | None, subtype: str | None, plugins: Plugins | None,
                         progress: Callable[[str], None] | None, settings: dict[str, Any], every: bool) -> list[Reconstruction]:
    """Segment with each candidate family, judge its separate objects largest first (the first
    accepted only, unless ``every``), keep the family whose first accepted object the frontal
    gate is surest of, and reconstruct its accepted objects."""
    plugins = plugins or Plugins()
    report = Report()
    name = str(image) if isinstance(image, (str, Path)) else "image"
    report.data["input"] = name
    with report.stage("load", progress):
        rgb = read_image(Path(image)) if isinstance(image, (str, Path)) else as_rgb(image)
        report.data["image_size"] = [int(rgb.shape[1]), int(rgb.shape[0])]
        user_mask = _load_optional_mask(mask, rgb.shape[:2], "mask")
        user_occluders = _load_optional_mask(occluder_mask, rgb.shape[:2], "occluder mask")

    candidates = [plugins.family(family)] if family not in (None, "auto") else list(plugins.families.values())
    if not candidates:
        raise UnknownFamilyError("no family plugin is installed (see `frontal3d plugins`)")
    several_families = len(candidates) > 1
    chosen: tuple[Family, dict[str, Any], list[_Accepted], list[tuple[int, str]], int] | None = None
    rejections: list[str] = []
    judged_outlines: dict[str, np.ndarray] = {}
    people: np.ndarray | None = None
    people_evidence: str | None = None
    for index, fam in enumerate(candidates):
        fam_settings = plugins.settings(fam.name, settings)
        with report.stage(f"segment[{fam.name}]" if several_families else "segment", progress):
            segmentation = segment_object(plugins, rgb, fam, fam_settings, user_mask, user_occluders, subtype, report)
            if index == 0:
                # What the user marked as occluders is explained already: a painted arm the
                # segmenter takes for a person must not vouch for one (see occluders.OFF_OBJECT_SHARE).
                people, people_evidence = people_detector.detect_people_with_evidence(
                    rgb, segmentation.object_mask if user_occluders is None else segmentation.object_mask | user_occluders)
                if people_evidence:
                    report.data["people_found_by"] = people_evidence
        accepted: list[_Accepted] = []
        turned_down: list[tuple[int, NotFrontalError]] = []
        for rank, object_mask in enumerate(segmentation.objects):
            judge = functools.partial(_judge_object, plugins, rgb, fam, fam_settings, subtype, rank, object_mask, segmentation, people)
            stage = f"classify[{fam.name}]" if several_families else "classify"
            # Without people's pixels beside the object there is no outline to free, and a
            # second judgement would repeat the first.
            beside = (_touching(people, object_mask) & ~object_mask).any()
            try:
                accepted.append(_judged_freeing_people(judge, people_evidence if beside else None, report, stage, progress))
            except NotFrontalError as exc:
                turned_down.append((rank, exc))
                continue
            if not every:
                break
        if not accepted:
            judged_outlines[fam.name] = segmentation.objects[turned_down[0][0]]
            if not several_families:
                raise _with_mask_hint(turned_down[0][1], report, judged_outlines)
            rejections.append(f"{fam.name}: {turned_down[0][1]}")
            continue
        if chosen is None or accepted[0].frontal_confidence > chosen[2][0].frontal_confidence:
            chosen = (fam, fam_settings, accepted, [(rank, str(exc)) for rank, exc in turned_down], len(segmentation.objects))
    if chosen is None:
        raise _with_mask_hint(NotFrontalError("no installed family accepts this image: " + "; ".join(rejections)), report,
                              judged_outlines)
    fam, fam_settings, accepted, turned_down, found = chosen
    results = []
    for candidate in accepted:
        _note_object_choice(candidate, found, turned_down, every, first=candidate is accepted[0])
        candidate.report.data["family"] = fam.name
        candidate.report.data["subtype"] = candidate.subtype
        candidate.report.data["decisions"] = [d.to_dict() for d in candidate.decisions]
        results.append(_reconstruct_shape_and_texture(
            plugins, rgb, candidate.object_mask, candidate.probable, candidate.occluders, candidate.people_near, fam,
            candidate.subtype, fam_settings, candidate.renders_by_subtype[candidate.subtype], candidate.report, progress,
            candidate.context, occluders_given=user_occluders is not None))
    return results


def _refuse_mostly_rebuilt(share: float, fam: Family, settings: dict[str, Any], object_mask: np.ndarray) -> None:
    """Raise :class:`NotFrontalError` when ``share`` (the occlusion stage's ``occluded_fraction``)
    says most of the object's front would be the template's, rebuilt behind people or occluders
    the detectors found (``max_rebuilt_share``).

    The occlusion stage trusts the detectors: behind a person in front, the outline is the
    template's. When what the segmenter found is a scrap of the photo (a cat's eyes, the
    coins between which a whole picture was taken for a person), the template is placed on
    the scrap, everything around it is "in front", and a confident model of the family comes
    out that the photo does not show. The issue's occluders hide 10-30 % of the object; the
    people benchmark's detections reach 0.48 of the rebuilt silhouette (seeds 0-2), such scraps 0.6-0.8.
    """
    limit = float(settings["max_rebuilt_share"])
    if share > limit:
        raise NotFrontalError(
            f"the {fam.name} is mostly hidden: {share:.0%} of its front would be the template's, rebuilt behind what was "
            f"taken for people or occluders (max_rebuilt_share = {limit:g}); if the photo shows a {fam.name}, give its mask "
            f"with --mask and what hides it with --occluder-mask", {fam.name: object_mask})


def _judged_freeing_people(judge: Callable[[bool, Report], _Accepted], evidence: str | None, report: Report, stage: str,
                           progress: Callable[[str], None] | None) -> _Accepted:
    """``judge(free_outline, trial_report)`` with the outline next to people freed, and when only
    the segmenter vouches for them and the gate turns the object down, again with that outline
    voting (see :data:`TRUSTED_PEOPLE_EVIDENCE`). ``evidence``: what vouched for the people beside
    the object, None when there are none. Each try writes into its own copy of ``report``; the
    second says why it ran (``people_judged_again``)."""
    def attempt(free_outline: bool, why: str | None = None) -> _Accepted:
        trial = copy.deepcopy(report)
        if why:
            trial.data["people_judged_again"] = why
        with trial.stage(stage, progress):
            return judge(free_outline, trial)

    try:
        return attempt(bool(evidence))
    except NotFrontalError as exc:
        if not evidence or evidence in TRUSTED_PEOPLE_EVIDENCE:
            raise
        why = f"with the outline next to a person only the segmenter found left out: {exc}; judged again with it"
    return attempt(False, why)


def _judge_object(plugins: Plugins, rgb: np.ndarray, fam: Family, settings: dict[str, Any], subtype: str | None, rank: int,
                  object_mask: np.ndarray, segmentation: Segmentation, people: np.ndarray | None, free_outline: bool,
                  report: Report) -> _Accepted:
    """Run the classifier chain on one of the separate objects; raises :class:`NotFrontalError`.
    ``free_outline``: see :func:`_people_in_front` and :data:`TRUSTED_PEOPLE_EVIDENCE`."""
    # People touching the object may stand in front of it or behind it: the template
    # placed on the object tells which, here for the classifiers and the alignment,
    # and again once aligned (occlusion stage).
    own_occluders = _without_people_off_object(segmentation.occluders, people, object_mask, segmentation.user_occluders)
    if own_occluders is not segmentation.occluders:
        judged = np.count_nonzero(segmentation.occluders) - (0 if own_occluders is None else np.count_nonzero(own_occluders))
        if judged:
            report.data["detected_occluder_pixels_judged_with_people"] = int(judged)
    object_mask, people_near, occluders = _with_people_judged(
        plugins, fam, settings, subtype, object_mask, segmentation.segmented, people, own_occluders, free_outline=free_outline,
        report=report)
    touching = _touching(occluders, object_mask)
    probable = _probable_shape(object_mask, touching)
    hidden = occlusion.hidden_by(touching, object_mask) if touching.any() else None
    # Whether the outline next to a person is the object's is unknown, in front or
    # behind: the person's pixels off the object do not vote on the view (on the
    # object they are often the held object itself).
    people_off = people_near & ~object_mask
    view_hidden = occlusion.hidden_by(people_off, object_mask) if people_off.any() else None
    decisions, picked_subtype, renders_by_subtype, context = run_classifiers(plugins, rgb, probable, fam, settings, subtype, hidden, view_hidden)
    return _Accepted(rank, object_mask, probable, occluders, people_near, decisions, picked_subtype, renders_by_subtype, context, report)


def _note_object_choice(candidate: _Accepted, found: int, turned_down: list[tuple[int, str]], every: bool, first: bool) -> None:
    """Say in the report which of the separate objects this is and why others were left out
    (with ``every``, the first object's report names all that were)."""
    report = candidate.report
    report.data["objects"] = {"found": found, "rank": candidate.rank + 1,
                              "turned_down": [{"rank": rank + 1, "reason": reason} for rank, reason in turned_down]}
    pixels = int(candidate.object_mask.sum())
    if every and found > 1:
        report.warn(f"{found} separate objects found; this is object {candidate.rank + 1} by size ({pixels} pixels)")
        for rank, reason in turned_down if first else ():
            report.warn(f"object {rank + 1} by size turned down by the classifier chain: {reason}")
    elif candidate.rank > 0:
        report.warn(f"{found} separate objects found; the {candidate.rank} larger one(s) turned down by the classifier chain "
                    f"({turned_down[0][1]}); reconstructing object {candidate.rank + 1} by size ({pixels} pixels)")
    elif found > 1:
        report.warn(f"{found} separate objects found; reconstructing the largest ({pixels} pixels; --all reconstructs each)")
    if _touches_border(candidate.object_mask):
        report.warn("the object touches the image border: parts of it may be cut off")


def _reconstruct_shape_and_texture(
    plugins: Plugins,
    rgb: np.ndarray,
    object_mask: np.ndarray,
    probable_shape: np.ndarray,
    occluders: np.ndarray | None,
    people_near: np.ndarray,
    fam: Family,
    subtype: str,
    settings: dict[str, Any],
    renders: TemplateRenders,
    report: Report,
    progress: Callable[[str], None] | None,
    context: classify.ClassifierContext,
    occluders_given: bool,
) -> Reconstruction:
    """The shape and texture stages for one accepted object. ``occluders_given``: the user gave
    the occluders (``--occluder-mask``), whose word is taken however much they hide."""
    maps: dict[str, np.ndarray] = {}
    # The crop also covers occluders touching the object: the rebuilt outline lies under them.
    crop = _crop_for(object_mask | _touching(occluders, object_mask) | (people_near & _around(object_mask)), int(settings["working_resolution"]))
    work_rgb = _to_working(rgb[..., :3], crop, cv2.INTER_AREA)
    work_mask = _to_working(object_mask.astype(np.uint8), crop, cv2.INTER_NEAREST) > 0
    report.data["working_size"] = [int(work_mask.shape[1]), int(work_mask.shape[0])]
    # Where the working grid (the debug maps' grid) lies in the input image.
    report.data["crop"] = {"x": crop.x0, "y": crop.y0, "width": crop.width, "height": crop.height}

    with report.stage("align", progress):
        work_grey = cv2.cvtColor(work_rgb, cv2.COLOR_RGB2GRAY)
        template_grey = _shade(renders.front_normals, renders.mask)
        work_shape = _to_working(probable_shape.astype(np.uint8), crop, cv2.INTER_NEAREST) > 0
        partly_hidden = isinstance(context, occlusion.VisibleAgreementContext) and context.hidden is not None
        hidden = _to_working(context.hidden.astype(np.uint8), crop, cv2.INTER_NEAREST) > 0 if partly_hidden else None
        similarity, diagnostics = align.align_template(
            renders.mask, work_shape, template_grey, work_grey, max_angle=np.deg2rad(settings["max_angle_deg"]), hidden=hidden
        )
        # The mutual information also weighs the grey image and may agree worse with the
        # (visible) outline than the classifier's placement, from masks alone, does.
        placed = _working_similarity(context.agreement()[subtype].similarity, crop)
        diagnostics["source"] = "mutual information"
        slack = 0.0 if partly_hidden else MI_OUTLINE_SLACK
        if occlusion.seen_iou(renders.mask, placed, work_mask, hidden) > occlusion.seen_iou(renders.mask, similarity, work_mask, hidden) + slack:
            similarity, diagnostics["source"] = placed, "classifier (agrees better with the visible outline)"
        report.data["alignment"] = {**similarity.to_dict(), **{k: _plain(v) for k, v in diagnostics.items()}}
        aligned_template_mask = align.warp_mask(renders.mask, similarity, work_mask.shape)
        aligned_template_regions = align.warp_labels(renders.front_regions, similarity, work_mask.shape)
        maps["aligned_template_mask"] = aligned_template_mask
    k = int(settings["boundary_k"]) or boundary.default_k(max(work_mask.shape))

    with report.stage("occlusion", progress):
        work_occluders = _to_working(occluders.astype(np.uint8), crop, cv2.INTER_NEAREST) > 0 if occluders is not None else np.zeros_like(work_mask)
        mirror_axis = _mirror_axis(settings, renders, similarity) if people_near.any() or work_occluders.any() else None
        work_people = np.zeros_like(work_mask)
        if people_near.any():
            work_people = _to_working(people_near.astype(np.uint8), crop, cv2.INTER_NEAREST) > 0
            work_occluders |= occlusion.in_front(work_people, work_mask, aligned_template_mask, mirror_axis)
        rebuilt = occlusion.rebuild_silhouette(work_mask, work_occluders, aligned_template_mask, k=k, mirror_axis=mirror_axis)
        seen_mask = work_mask
        pictured = work_occluders.any() or people_near.any()
        if pictured:
            maps.update(seen_object_mask=seen_mask, people=work_people, occluders=work_occluders)
        work_mask, occluded = rebuilt.mask, rebuilt.occluded
        report.data["occlusion"] = rebuilt.summary()
        if not occluders_given:
            _refuse_mostly_rebuilt(report.data["occlusion"]["occluded_fraction"], fam, settings, object_mask)
        if settings["fill_holes"] and _found_by_segmenters(report):
            work_mask, filled = _template_holes_filled(work_mask, aligned_template_mask)
            if filled:
                report.data["filled_hole_pixels"] = filled
        maps["occlusion_mask"] = occluded

    with report.stage("regions", progress):
        transferred = np.where(work_mask, aligned_template_regions, -1)
        maps["transferred_regions"] = transferred
        regions = plugins.hook.frontal3d_segment_regions(
            image=work_rgb, object_mask=work_mask, transferred_regions=transferred, family=fam, subtype=subtype, settings=settings
        )
        if regions is None:
            regions = transferred
        regions = occlusion.rebuild_regions(regions, work_mask, occluded, len(renders.region_names))
        maps["regions"] = regions
        if pictured:
            maps["occlusion_sheet"] = occlusion.occlusion_sheet(work_rgb, seen_mask, work_people, work_occluders, aligned_template_mask,
                                                                work_mask, debug_picture(regions), occluded)

    with report.stage("boundary", progress):
        # Both outlines on the working grid, pieces joined the same way on both sides.
        join = _pieces(work_mask) > 1 or _pieces(aligned_template_mask) > 1
        input_contour = boundary.trace_contour(_joined(work_mask) if join else work_mask)
        template_contour = boundary.trace_contour(_joined(aligned_template_mask) if join else aligned_template_mask).astype(np.float64)
        omega = boundary.match_contours(input_contour, template_contour, k)
        region_k = int(settings["region_k"])
        refined = boundary.match_regions(regions, aligned_template_regions, input_contour, template_contour, omega, K=region_k)
        omega = _guarded_refinement(input_contour, template_contour, omega, refined, work_mask.shape)
        inner_in, inner_tpl = boundary.region_pivots(regions, aligned_template_regions, K=region_k)
        inner_in, inner_tpl = _consistent_pivots(input_contour, template_contour[omega], inner_in, inner_tpl, work_mask.shape)
        out_pivots = np.concatenate([input_contour, inner_in])
        src_pivots = np.concatenate([template_contour[omega], inner_tpl])
        report.data["boundary"] = {"k": k, "contour_points": int(len(input_contour)), "region_pivots": int(len(inner_in))}

    with report.stage("warp", progress):
        warped = warp.warp_template_to_silhouette(work_mask, renders.maps(), similarity.matrix, out_pivots, src_pivots)

    with report.stage("mesh", progress):
        pixel_size = renders.pixel_size / similarity.scale
        relative_scale = _depth_scale(warped.local_scale / similarity.scale, work_mask, settings["depth_scale"], renders.mask, similarity)
        front_z = warped.front_depth * relative_scale
        back_z = warped.back_depth * relative_scale
        rule = _rule(plugins.hook.frontal3d_symmetry_rules(), settings["symmetry"], "symmetry")
        front_z, back_z = rule(front_z, back_z, work_mask, regions, {})
        result = mesh.build_mesh(
            work_mask, front_z, back_z, pixel_size,
            smooth_iterations=int(settings["smooth_iterations"]),
            max_vertices=int(settings["max_vertices"]) or None,
        )
        if result.dropped_pixels:
            report.warn(f"{result.dropped_pixels} one-pixel pinch or isolated pixel(s) dropped from the silhouette to keep the mesh closed")
        landmarks = _warp_landmarks(renders, warped, relative_scale, result, pixel_size)
        maps.update(front_depth=front_z, back_depth=back_z)

    with report.stage("texture", progress):
        full_crop = rgb[crop.y0 : crop.y0 + crop.height, crop.x0 : crop.x0 + crop.width, :3]
        texture_scale = _texture_scale(crop, int(settings["max_texture_side"]))
        texture_size = (max(1, int(crop.width * texture_scale)), max(1, int(crop.height * texture_scale)))  # floored: within the limit
        if texture_scale < 1.0:
            report.warn(f"texture kept at {texture_scale:.2f} of the photo's resolution: its atlas (front and back side by side) "
                        f"would be wider than max_texture_side = {settings['max_texture_side']} px")
        full_mask = cv2.resize(work_mask.astype(np.uint8), (crop.width, crop.height), interpolation=cv2.INTER_NEAREST) > 0
        full_occluded = cv2.resize(occluded.astype(np.uint8), (crop.width, crop.height), interpolation=cv2.INTER_NEAREST) > 0
        if full_occluded.any() or people_near.any():
            # Next to people judged behind, the working grid's coarse outline still takes in
            # slivers of them: like rebuilt pixels, those are inpainted, not taken from the photo.
            window = np.s_[crop.y0 : crop.y0 + crop.height, crop.x0 : crop.x0 + crop.width]
            full_occluders = None if occluders is None else occluders[window]
            full_occluded = occlusion.occluded_at_full_resolution(full_occluded, full_mask, object_mask[window], full_occluders)
        report.data["occlusion"]["inpainted_pixels"] = int(np.count_nonzero(full_occluded & full_mask))
        if texture_scale < 1.0:
            full_crop = cv2.resize(full_crop, texture_size, interpolation=cv2.INTER_AREA)
            full_mask = cv2.resize(work_mask.astype(np.uint8), texture_size, interpolation=cv2.INTER_NEAREST) > 0
            # Any texel an occluded pixel falls in is inpainted, so no occluder colour is averaged in.
            full_occluded = cv2.resize(full_occluded.astype(np.uint8) * 255, texture_size, interpolation=cv2.INTER_AREA) > 0
        full_regions = cv2.resize(regions.astype(np.int16), texture_size, interpolation=cv2.INTER_NEAREST).astype(np.int32)
        back_rules = {}
        for rules in plugins.hook.frontal3d_back_texture_rules():
            back_rules.update(rules)
        back_rule = _rule([back_rules], settings["back_texture"], "back_texture")
        textured = texture.build_textured_mesh(
            result, full_crop, full_mask, full_regions, full_occluded, renders.region_names,
            back_rule, dict(settings["back_texture_params"]), working_to_full=texture_scale / crop.scale,
            bump_strength=float(settings["bump_strength"]),
        )

    # Centred at the bounding-box centre, in the template's metres unless the user gave a size.
    centre = textured.watertight_mesh.bounds.mean(axis=0)
    size = float(settings["size_m"])
    scale = size / float(textured.watertight_mesh.extents.max()) if size > 0 else 1.0
    geometries = [textured.mesh] if textured.mesh is textured.watertight_mesh else [textured.mesh, textured.watertight_mesh]
    for geometry in geometries:
        geometry.apply_translation(-centre)
        geometry.apply_scale(scale)
    landmarks = {name: (position - centre) * scale for name, position in landmarks.items()}
    report.data["mesh"] = {
        "vertices": int(len(textured.watertight_mesh.vertices)),
        "faces": int(len(textured.watertight_mesh.faces)),
        "watertight": bool(textured.watertight_mesh.is_watertight),
        "size_m": [round(float(v), 4) for v in textured.watertight_mesh.extents],
    }
    report.data["seconds_total"] = round(sum(report.data["stages"].values()), 3)
    maps["object_mask"] = work_mask
    return Reconstruction(textured=textured, landmarks=landmarks, report=report.data, maps=maps)


class Segmentation(NamedTuple):
    """What :func:`segment_object` finds: the separate objects (largest first), the occluders
    and every piece the segmenter found (people found later may join more of them to an object)."""

    objects: list[np.ndarray]
    occluders: np.ndarray | None
    segmented: np.ndarray
    user_occluders: np.ndarray | None = None

    @property
    def object_mask(self) -> np.ndarray:
        """The largest object."""
        return self.objects[0]


def segment_object(plugins: Plugins, rgb: np.ndarray, fam: Family, settings: dict[str, Any], user_mask: np.ndarray | None = None,
                   user_occluders: np.ndarray | None = None, subtype: str | None = None,
                   report: Report | None = None) -> Segmentation:
    """The objects' masks and the occluders, as reconstruction finds them before classifying:
    the segmenter chain, the occluder detectors, the pieces grouped into objects and, with
    the ``shape_prior`` setting, GrabCut's mask of the largest cut again with the templates and,
    with ``mirror_repair``, each object's mask mended by its mirror image (stages.mirror_repair).
    People's faces are cut from what the segmenters find (segment.without_faces).
    The mask benchmark (frontal3d.eval_masks) scores exactly the largest object's mask."""
    report = report or Report()
    found = _segment(plugins, rgb, fam, settings, user_mask, report)
    segmented_here = _found_by_segmenters(report)
    faces = people_detector.detect_faces(rgb) if segmented_here else None
    if faces is not None and (found & faces).any():
        without = segment.without_faces(found, faces)
        report.data["face_pixels_cut"] = int(np.count_nonzero(found & ~without))
        found = without
    occluders = occlusion.find_occluders(plugins, rgb, found, settings, user_occluders, report.data)
    objects = separate_objects(found, occluders, fam)
    if settings["shape_prior"] and report.data["segmenter"] == "GrabCut (training-free)":
        # The largest only (2-4 s each): the others are judged only when it is turned down or with --all.
        objects[0] = _refine_with_templates(plugins, rgb, objects[0], occluders, fam, settings, subtype, report)
    if settings["mirror_repair"] and segmented_here and occluders is None:
        # Not a mask the user gave, nor one with people in front: those may be rightly lopsided.
        # The network's doubt is asked only where it may cut a piece of the object's own colour.
        network = learned_dense.configured_segmenter(settings, fam, rgb[..., :3]) if settings["mirror_repair_cuts_own_colour"] else None
        probability = network.object_probability_either_tone(rgb) if network is not None else None
        paired = settings["mirror_repair_paired_colours"]
        objects = [_mirror_repaired(rgb, mask, probability, paired, index, report) for index, mask in enumerate(objects)]
    return Segmentation(objects, occluders, found, user_occluders)


def _mirror_repaired(rgb: np.ndarray, mask: np.ndarray, probability: np.ndarray | None, paired_colours: bool, index: int,
                     report: Report) -> np.ndarray:
    """One object's mask after the mirror repair, noted in report.json when it changed anything
    (``index`` counts the objects found, largest first)."""
    repaired, summary = mirror_repair.mirror_repaired(rgb, mask, probability, paired_colours)
    if summary.get("cut_px") or summary.get("added_px"):
        report.data.setdefault("mirror_repair", []).append({"object": index} | summary)
    return repaired


def _segment(plugins: Plugins, rgb: np.ndarray, fam: Family, settings: dict[str, Any], user_mask: np.ndarray | None, report: Report) -> np.ndarray:
    """Ask the segmenter chain (first answer wins) and name the segmenter that answered in the report.

    The chain's implementations are called here in pluggy's own first-result order (last
    registered and ``tryfirst`` first), so the report can say which one produced the mask.
    A plugin that wraps the hook needs pluggy's own call; the report then names the chain.
    """
    arguments = {"image": rgb, "family": fam, "settings": settings, "hints": {"mask": user_mask}}
    impls = plugins.pm.hook.frontal3d_segment.get_hookimpls()
    found = None
    if any(impl.hookwrapper or impl.wrapper for impl in impls):
        found = plugins.hook.frontal3d_segment(**arguments)
        report.data["segmenter"] = "segmenter chain (wrapped by a plugin)"
    else:
        for impl in reversed(impls):
            found = impl.function(**{name: arguments[name] for name in impl.argnames})
            if found is not None:
                report.data["segmenter"] = _segmenter_name(impl, user_mask, settings, rgb)
                break
    if found is None or not np.asarray(found).any():
        raise NoObjectError(f"no {fam.name} found in the image (give a mask with --mask if the object is there)")
    return np.asarray(found, dtype=bool)


def _segmenter_name(impl: Any, user_mask: np.ndarray | None, settings: dict[str, Any], rgb: np.ndarray) -> str:
    """What report.json calls the segmenter that answered."""
    if impl.plugin_name != "frontal3d":
        return f"plugin {impl.plugin_name} ({impl.function.__name__})"
    if impl.function.__name__ == "learned_segmenter":
        return f"learned segmenter ({learned_dense.segmenter_weights(settings, rgb[..., :3])})"
    if impl.function.__name__ == "classical_segmenter":
        return "GrabCut (training-free)"
    return "user mask" if user_mask is not None else "alpha channel"


def separate_objects(found: np.ndarray, occluders: np.ndarray | None, fam: Family) -> list[np.ndarray]:
    """The separate objects of the segmented area, largest first: each is the largest piece
    left and the pieces near it (or joined to it through an occluder, like a guitar neck an
    arm cuts off)."""
    pieces = segment.split_objects(found)
    if not pieces:
        raise NoObjectError(f"no {fam.name} found in the image: the segmented area is too small")
    objects = []
    while pieces:
        chosen, pieces = _group_near_largest(pieces, occluders)
        chosen |= _pieces_across_occluders(found, occluders, chosen)
        pieces = [piece for piece in pieces if not (piece & chosen).any()]
        objects.append(chosen)
    return objects


def _group_near_largest(objects: list[np.ndarray], occluders: np.ndarray | None = None) -> tuple[np.ndarray, list[np.ndarray]]:
    """The largest component plus every component near it (a wheel or tail the mask split
    off belongs to the same object), and the components left out, largest first.

    "Near" is within 8 % of the largest component's longest side, counted across any
    occluder touching the largest component.
    """
    chosen = objects[0].copy()
    ys, xs = np.nonzero(chosen)
    radius = max(2, int(0.08 * max(np.ptp(ys), np.ptp(xs))))
    reach = within(chosen | _touching(occluders, chosen), radius)
    left_out = []
    for component in objects[1:]:
        if (component & reach).any():
            chosen |= component
        else:
            left_out.append(component)
    return chosen, left_out


def _pieces_across_occluders(found: np.ndarray, occluders: np.ndarray | None, chosen: np.ndarray) -> np.ndarray:
    """Pieces of ``found`` an occluder touching ``chosen`` cut off from it, however small
    (the tail of a guitar below a strumming arm is not clutter: it fixes the body's length),
    and in turn the pieces the occluders touching those cut off (a headstock beyond a
    forearm whose hand, a separate occluder piece, lies on the neck)."""
    touching = _touching(occluders, chosen)
    if not touching.any():
        return np.zeros_like(chosen)
    _count, labels, stats, _ = cv2.connectedComponentsWithStats(found.astype(np.uint8), connectivity=8)
    joined = np.zeros_like(chosen)
    while True:
        near = cv2.dilate(touching.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        across = np.unique(labels[near & found])
        across = across[(across > 0) & (stats[across, cv2.CC_STAT_AREA] >= segment.MIN_OBJECT_PIXELS)]
        grown = np.isin(labels, across)
        if not (grown & ~joined).any():
            return joined
        joined |= grown
        touching = _touching(occluders, chosen | joined)


def _with_people_judged(plugins: Plugins, fam: Family, settings: dict[str, Any], subtype: str | None, object_mask: np.ndarray,
                        segmented: np.ndarray, people: np.ndarray | None, occluders: np.ndarray | None,
                        free_outline: bool, report: Report | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The object mask, the people touching it and the occluders once those people are judged
    in front or behind (:func:`_people_in_front`, with ``free_outline``). Pieces a person in
    front cut off join the object, which is then judged again, and the gap to each such piece
    counts as in front too."""
    people_near = _touching(people, object_mask)
    if not people_near.any():
        return object_mask, people_near, occluders

    def in_front_of(mask: np.ndarray, near: np.ndarray) -> np.ndarray:
        probable = _probable_shape(mask, _touching(occluders, mask))
        return _people_in_front(plugins, fam, settings, subtype, mask, probable, near, free_outline=free_outline, report=report)

    in_front = in_front_of(object_mask, people_near)
    bridged = _pieces_across_people(segmented, people, in_front, object_mask) if in_front.any() else in_front
    if bridged.any():
        # A headstock beyond a person over the neck: judged again with the whole object.
        object_mask = object_mask | bridged
        people_near = _touching(people, object_mask)
        in_front = in_front_of(object_mask, people_near) | _gaps_to(bridged, object_mask & ~bridged)
    if in_front.any():
        occluders = in_front if occluders is None else occluders | in_front
    return object_mask, people_near, occluders


def _without_people_off_object(occluders: np.ndarray | None, people: np.ndarray | None, object_mask: np.ndarray,
                               user_occluders: np.ndarray | None) -> np.ndarray | None:
    """The occluders less the detected ones on people's pixels off the object: a pose model
    draws a guitarist's arms whether they are in front of the object or behind it, and an arm
    band beside the object would hide the outline it borders. Those pixels are judged with the
    rest of the person (:func:`_people_in_front`: in front where the placed template expects
    the object). Detected pixels on the object (judged by colour) and the user's stand."""
    if occluders is None or people is None:
        return occluders
    judged = people & ~object_mask
    if user_occluders is not None:
        judged &= ~user_occluders
    kept = occluders & ~judged
    return kept if kept.any() else None


def _pieces_across_people(segmented: np.ndarray, people: np.ndarray, in_front: np.ndarray, object_mask: np.ndarray) -> np.ndarray:
    """Pieces of ``segmented`` left out of ``object_mask`` that a person standing in front of
    it also touches: the person, not background, cut them off (the headstock beyond an
    astronaut over the neck). People are found after the pieces are chosen, so
    :func:`separate_objects` could not join them. The person is the whole connected stretch of
    people's pixels off the object holding in-front pixels, not just those pixels: the
    in-front pixels are where the template placed without the piece expects the object.
    Only whole pieces join: what a shape prior cut off the chosen piece stays off."""
    _count, pieces = cv2.connectedComponents(segmented.astype(np.uint8), connectivity=8)
    left_out = segmented & ~np.isin(pieces, np.unique(pieces[object_mask]))
    off_object = (np.asarray(people, dtype=bool) | in_front) & ~object_mask
    _count, labels = cv2.connectedComponents(off_object.astype(np.uint8), connectivity=8)
    in_front_people = np.isin(labels, np.unique(labels[in_front & off_object]))
    return _pieces_across_occluders(left_out, in_front_people & off_object, object_mask)


def _gaps_to(pieces: np.ndarray, object_mask: np.ndarray) -> np.ndarray:
    """The background between each piece and the object, hidden like the person who cut the
    piece off (a dark helmet over the neck the person segmenter loses): the pixels whose
    distances to both add up to at most GAP_SLACK times the shortest way across."""
    to_object = cv2.distanceTransform((~object_mask).astype(np.uint8), cv2.DIST_L2, 5)
    gaps = np.zeros_like(object_mask)
    count, labels = cv2.connectedComponents(pieces.astype(np.uint8), connectivity=8)
    for label in range(1, count):
        piece = labels == label
        across = to_object + cv2.distanceTransform((~piece).astype(np.uint8), cv2.DIST_L2, 5)
        gaps |= across <= GAP_SLACK * to_object[piece].min()
    return gaps & ~object_mask & ~pieces


def _touching(occluders: np.ndarray | None, mask: np.ndarray) -> np.ndarray:
    """The occluder pieces that touch ``mask`` (empty when there are no occluders)."""
    if occluders is None or not occluders.any():
        return np.zeros_like(mask)
    return pieces_touching(occluders, mask, np.ones((5, 5), np.uint8))


def _refine_with_templates(plugins: Plugins, rgb: np.ndarray, object_mask: np.ndarray, occluders: np.ndarray | None,
                           fam: Family, settings: dict[str, Any], forced_subtype: str | None, report: Report) -> np.ndarray:
    """GrabCut's mask cut again with each subtype's template, placed on it as the classifiers
    place it, as the shape prior (segment.refine_with_shape_prior); kept when no template helps.
    Runs before the classifiers: the frontal gate would reject a wingless mask first.
    Only GrabCut's masks: a user's mask, an alpha channel or a learned mask stands as given."""
    renders = _subtype_renders(plugins, fam, settings, forced_subtype)
    max_angle = np.deg2rad(float(settings["max_angle_deg"]))
    past_box = classify.counts_template_past_box(settings)
    agreement = classify.silhouette_agreement(object_mask, renders, max_angle, past_box=past_box)
    refined = segment.refine_with_shape_prior(rgb, object_mask, renders, agreement, max_angle, exclude=occluders, past_box=past_box)
    report.data["shape_prior_changed_pixels"] = 0 if refined is object_mask else int(np.count_nonzero(refined ^ object_mask))
    if refined is object_mask:
        return object_mask
    return _group_near_largest(segment.split_objects(refined), occluders)[0]


def _people_in_front(plugins: Plugins, fam: Family, settings: dict[str, Any], subtype: str | None,
                     object_mask: np.ndarray, probable: np.ndarray, people_near: np.ndarray, free_outline: bool = False,
                     report: Report | None = None) -> np.ndarray:
    """The people's pixels in front of the object, judged by the best-fitting subtype's
    template placed on the object as seen: the classifiers and the alignment then leave
    them out like found arms (a torso in front of a guitar is not a notch in its body).

    With ``free_outline`` the outline next to the people's pixels off the object does not
    vote on that placement: it may be a person's edge (beside, behind or in front), which
    would drag the template towards the person. But where people surround the object, hardly
    any outline is left to vote, and the freed template can turn across them (a guitarist's
    body behind the whole guitar then stands "in front" all round it), while with the outline
    voting a person's edge can turn it too. So both are placed, and when they turn more than
    MAX_FREED_TURN_DEG apart, the one whose long axis lies closer to the object's stands.
    ``report`` learns which placement judged (``people_judged_with``): the one to look at when
    a person is taken for in front or behind the wrong way."""
    renders = _subtype_renders(plugins, fam, settings, subtype)
    people_off = people_near & ~object_mask
    hidden = occlusion.hidden_by(people_off, object_mask) if free_outline and people_off.any() else None
    max_angle = np.deg2rad(float(settings["max_angle_deg"]))

    def placement(hidden: np.ndarray | None) -> tuple[np.ndarray, TemplateRenders, align.Similarity]:
        agreement = classify.silhouette_agreement(probable, renders, max_angle, hidden=hidden)
        best = max(agreement, key=lambda s: agreement[s].iou)
        return align.warp_mask(renders[best].mask, agreement[best].similarity, object_mask.shape), renders[best], agreement[best].similarity

    placed, render, similarity = placement(hidden)
    judged_with: dict[str, Any] = {"outline": "whole" if hidden is None else "without the outline next to people"}
    if hidden is not None:
        voted = placement(None)
        turn = _turn_between(similarity.angle, voted[2].angle, 2 * np.pi)
        judged_with["placements_apart_deg"] = round(float(np.rad2deg(turn)), 1)
        if turn > np.deg2rad(MAX_FREED_TURN_DEG):
            axis = align.mask_moments(probable)[2]
            if _turn_between(align.mask_moments(voted[0])[2], axis, np.pi) < _turn_between(align.mask_moments(placed)[2], axis, np.pi):
                placed, render, similarity = voted
                judged_with["outline"] = "whole (the freed placement turned across the people)"
    if report is not None:
        report.data["people_judged_with"] = judged_with
    return occlusion.in_front(people_near, object_mask, placed, _mirror_axis(settings, render, similarity))


def _turn_between(a: float, b: float, period: float) -> float:
    """The smaller angle between two directions given modulo ``period`` (2 pi: angles; pi: axes)."""
    return abs((a - b + period / 2) % period - period / 2)


def _mirror_axis(settings: dict[str, Any], renders: TemplateRenders, similarity: align.Similarity) -> float | None:
    """The placed template's mirror line (radians from image-up) when the family rebuilds outlines by mirror, else None."""
    return np.deg2rad(template_mirror(renders)[1]) - similarity.angle if settings["outline_mirror"] else None


def _around(mask: np.ndarray) -> np.ndarray:
    """The mask's bounding box grown by PEOPLE_REACH of its size on every side: where a
    person in front may hide the object's outline (the crop must leave room to rebuild it)."""
    ys, xs = np.nonzero(mask)
    margin = int(np.ceil(PEOPLE_REACH * max(np.ptp(ys), np.ptp(xs))))
    around = np.zeros_like(mask, dtype=bool)
    around[max(0, ys.min() - margin) : ys.max() + margin + 1, max(0, xs.min() - margin) : xs.max() + margin + 1] = True
    return around


def _probable_shape(object_mask: np.ndarray, touching: np.ndarray) -> np.ndarray:
    """The object as the classifiers and the alignment should see it: the visible mask plus
    the occluded pixels (of the occluders ``touching`` it) inside its convex hull (an arm
    across a guitar body hides body, not background); the exact outline is rebuilt later
    from the aligned template."""
    if not touching.any():
        return object_mask
    points = cv2.findNonZero(object_mask.astype(np.uint8))
    hull = np.zeros(object_mask.shape, np.uint8)
    cv2.fillConvexPoly(hull, cv2.convexHull(points), 1)
    return object_mask | (touching & (hull > 0))


def run_classifiers(plugins: Plugins, rgb: np.ndarray, object_mask: np.ndarray, fam: Family, settings: dict[str, Any],
                    forced_subtype: str | None = None, hidden: np.ndarray | None = None, view_hidden: np.ndarray | None = None):
    """Run the classifier chain: (decisions, subtype, renders by subtype, context).

    Raises :class:`NotFrontalError` with the rejecting classifier's reason; ``hidden``
    (occluded pixels) is left out of the silhouette agreement, ``view_hidden`` (pixels that
    may or may not be the object's) out of the frontal gate's. Also the gate benchmark's
    entry point (:mod:`frontal3d.eval_gate`).
    """
    renders_by_subtype = _subtype_renders(plugins, fam, settings, forced_subtype)
    fields = dict(image=rgb, object_mask=object_mask, family=fam, renders=renders_by_subtype, settings=settings)
    if hidden is None and view_hidden is None:
        context = classify.ClassifierContext(**fields)
    else:
        context = occlusion.VisibleAgreementContext(**fields, hidden=hidden, view_hidden=view_hidden)
    classifiers = sorted((c for group in plugins.hook.frontal3d_classifiers(family=fam) for c in group), key=lambda c: c.order)
    decisions = []
    picked = forced_subtype
    for classifier in classifiers:
        if classifier.name == "subtype" and forced_subtype:
            continue
        decision = classifier.classify(context)
        decisions.append(decision)
        if not decision.accepted:
            raise NotFrontalError(decision.reason)
        if decision.name == "subtype":
            picked = decision.label
    if picked is None:
        picked = fam.subtypes[0]
    return decisions, picked, renders_by_subtype, context


def _texture_scale(crop: _Crop, max_side: int) -> float:
    """The share of the photo's resolution the texture keeps: all of it unless the atlas,
    the crop's front and back side by side, would be wider or taller than ``max_side``
    (0 = no limit). Game engines and VR headsets load textures up to 4096-16384 px a side."""
    longest = max(crop.height, 2 * crop.width)
    return 1.0 if max_side <= 0 or longest <= max_side else max_side / longest


def _working_similarity(full_similarity: align.Similarity, crop: _Crop) -> align.Similarity:
    """A template -> full-image similarity as template -> working pixels (cv2.resize's pixel centres)."""
    to_working = align.Similarity(crop.scale, 0.0, (0.5 - crop.x0) * crop.scale - 0.5, (0.5 - crop.y0) * crop.scale - 0.5)
    return to_working.compose(full_similarity)


def _subtype_renders(plugins: Plugins, fam: Family, settings: dict[str, Any], forced_subtype: str | None) -> dict[str, TemplateRenders]:
    """The renders of the subtypes in question: the one the user forced, else every subtype."""
    if forced_subtype is not None and forced_subtype not in fam.subtypes:
        raise UnknownFamilyError(f"family {fam.name!r} has no subtype {forced_subtype!r} (subtypes: {', '.join(fam.subtypes)})")
    subtypes = [forced_subtype] if forced_subtype else list(fam.subtypes)
    return {s: _renders(plugins, fam, s, settings) for s in subtypes}


def _renders(plugins: Plugins, fam: Family, subtype: str, settings: dict[str, Any]) -> TemplateRenders:
    template: Template | None = plugins.hook.frontal3d_template(family=fam, subtype=subtype, settings=settings)
    if template is None:
        raise TemplateError(f"no plugin provides a template for {fam.name}/{subtype}")
    return load_or_render(template, int(settings["template_resolution"]), cache_dir=plugins.config.cache_dir)


def _load_optional_mask(mask: np.ndarray | str | Path | None, shape: tuple[int, int], what: str) -> np.ndarray | None:
    if mask is None:
        return None
    if isinstance(mask, (str, Path)):
        return read_mask(Path(mask), shape)
    mask = mask_from_array(mask)
    if mask.shape != shape:
        raise InputError(f"{what} is {mask.shape[1]}x{mask.shape[0]} but the image is {shape[1]}x{shape[0]}")
    return mask


def _guarded_refinement(input_contour: np.ndarray, template_contour: np.ndarray, omega: np.ndarray, refined: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The per-region refinement of the outline matching, where it does not go astray.

    Region matches move a point's partner along the template outline so parts line up
    (a neck on the neck); a refined partner farther than 2 % of the object's size beyond
    the global one is a region mismatch (seen on thin airplane tails), so that point
    keeps its global partner.
    """
    tolerance = max(2.0, 0.02 * max(shape))
    global_distance = np.linalg.norm(input_contour - template_contour[omega], axis=1)
    refined_distance = np.linalg.norm(input_contour - template_contour[refined], axis=1)
    return np.where(refined_distance <= global_distance + tolerance, refined, omega)


def _consistent_pivots(outline_in: np.ndarray, outline_tpl: np.ndarray, inner_in: np.ndarray, inner_tpl: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Keep the inner region-boundary pivots that agree with the outline's warp.

    Region boundaries refine the warp locally (paper 3.2.4); a pair the per-region
    matching got wrong (a left wing matched to the right one) would tear the map, so a
    pair survives only when its template point lies within 2 % of the object's size of
    where the outline-only warp (evaluated coarsely) already sends its input point.
    """
    if len(inner_in) == 0:
        return inner_in, inner_tpl
    coarse = warp.mls_inverse_map(outline_in, outline_tpl, shape, grid_step=8)
    cols = np.clip(np.rint(inner_in[:, 0]).astype(int), 0, shape[1] - 1)
    rows = np.clip(np.rint(inner_in[:, 1]).astype(int), 0, shape[0] - 1)
    tolerance = max(2.0, 0.02 * max(shape))
    keep = np.linalg.norm(coarse[rows, cols] - inner_tpl, axis=1) <= tolerance
    return inner_in[keep], inner_tpl[keep]


def _with_mask_hint(error: NotFrontalError, report: Report, outlines: dict[str, np.ndarray]) -> NotFrontalError:
    """The chain's reason with the outlines it judged (per family) and, when they are the core
    segmenters' own, that a mask can be given: a wrong mask (a kerb taken in, a wing cut off) is
    turned down for a view it does not show."""
    if not _found_by_segmenters(report):
        return NotFrontalError(str(error), outlines)
    segmenter = report.data["segmenter"].split(" (")[0]
    return NotFrontalError(f"{error} (the outline judged is the {segmenter}'s: if it is not the object's, give a mask with --mask)",
                           outlines)


def _found_by_segmenters(report: Report) -> bool:
    """Whether the object's mask is the core segmenters' own, not the user's, an alpha channel's or a plugin's."""
    name = report.data.get("segmenter", "")
    return name == "GrabCut (training-free)" or name.startswith("learned segmenter")


def _template_holes_filled(mask: np.ndarray, aligned_template_mask: np.ndarray) -> tuple[np.ndarray, int]:
    """``mask`` with its holes filled where the template is solid (see MAX_FILLED_HOLE), and how many pixels that took."""
    holes = binary_fill_holes(mask) & ~mask
    count, labels, stats, _ = cv2.connectedComponentsWithStats(holes.astype(np.uint8), connectivity=4)
    if count <= 1:
        return mask, 0
    covered = np.bincount(labels[aligned_template_mask], minlength=count)
    areas = stats[:, cv2.CC_STAT_AREA]
    fill = (areas <= MAX_FILLED_HOLE * mask.sum()) & (covered >= TEMPLATE_COVERED_HOLE * areas)
    fill[0] = False
    if not fill.any():
        return mask, 0
    return mask | fill[labels], int(areas[fill].sum())


def _pieces(mask: np.ndarray) -> int:
    return cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)[0] - 1


def _joined(mask: np.ndarray) -> np.ndarray:
    """The mask closed just enough to join nearby pieces, so one outline traces the object.

    Used on the object and the aligned template alike (closing also fills notches, so
    both outlines must be traced the same way), only when either is in pieces.
    """
    ys, xs = np.nonzero(mask)
    radius = max(1, int(0.04 * max(np.ptp(ys), np.ptp(xs))))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    return cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, kernel) > 0


def _crop_for(mask: np.ndarray, working_resolution: int) -> _Crop:
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    margin = int(np.ceil(CROP_MARGIN * max(y1 - y0, x1 - x0)))
    y0, x0 = max(0, y0 - margin), max(0, x0 - margin)
    y1, x1 = min(mask.shape[0], y1 + margin), min(mask.shape[1], x1 + margin)
    scale = working_resolution / max(y1 - y0, x1 - x0)
    return _Crop(x0=int(x0), y0=int(y0), width=int(x1 - x0), height=int(y1 - y0), scale=float(scale))


def _to_working(array: np.ndarray, crop: _Crop, interpolation: int) -> np.ndarray:
    cropped = array[crop.y0 : crop.y0 + crop.height, crop.x0 : crop.x0 + crop.width]
    h, w = crop.working_shape
    return cv2.resize(cropped, (w, h), interpolation=interpolation)


def _depth_scale(relative_scale: np.ndarray, mask: np.ndarray, mode: str, template_mask: np.ndarray, similarity: align.Similarity) -> np.ndarray:
    """How much to scale the template's depth at each pixel (paper 3.2.5: "we scale the Z
    dimension accordingly"): ``local`` follows the warp's local stretch, ``smooth`` the
    same blurred over a tenth of the object, ``global`` only the alignment's scale,
    ``length`` the object's length against the aligned template's (:func:`_length_ratio`).
    """
    if mode == "global":
        return np.ones_like(relative_scale)
    if mode == "length":
        return np.full_like(relative_scale, _length_ratio(mask, template_mask, similarity))
    if mode == "smooth":
        sigma = 0.1 * max(mask.shape)
        weight = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), sigma)
        blurred = cv2.GaussianBlur(np.where(mask, relative_scale, 0).astype(np.float32), (0, 0), sigma)
        return np.where(weight > 1e-6, blurred / np.maximum(weight, 1e-6), 1.0)
    if mode == "local":
        return relative_scale
    raise ConfigError(f"depth_scale must be local, smooth, global or length, not {mode!r}")


def _length_ratio(object_mask: np.ndarray, template_mask: np.ndarray, similarity: align.Similarity) -> float:
    """The object's extent along the placed template's vertical axis over the template's own:
    an airplane's fin and fuselage depth follow its length, not the compromise between
    span and length that the alignment's scale strikes."""
    axis = np.array([-np.sin(similarity.angle), np.cos(similarity.angle)])
    rows, cols = np.nonzero(object_mask)
    extent = np.ptp(np.column_stack([cols, rows]) @ axis)
    return float(extent / (similarity.scale * np.ptp(np.nonzero(template_mask)[0])))


def _shade(normals: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """A grey rendering of the template (light from the camera) for mutual information."""
    grey = np.clip(normals[..., 2], 0.0, 1.0) * 200.0 + 40.0
    return np.where(mask, grey, 0).astype(np.uint8)


def _warp_landmarks(renders: TemplateRenders, warped: warp.WarpResult, relative_scale: np.ndarray, meshed: mesh.MeshResult, pixel_size: float) -> dict[str, np.ndarray]:
    """Send each template landmark through the warp: to the meshed pixel whose source is
    nearest, at the template's depth scaled like the surface there, kept between that
    pixel's back and front vertices so it stays on or inside the (smoothed) mesh.
    """
    vertices = np.asarray(meshed.mesh.vertices)
    front = meshed.vertex_side == 0
    front_pixels = np.rint(meshed.vertex_pixel[front]).astype(int)
    front_index = np.flatnonzero(front)
    back_of = {tuple(p): i for p, i in zip(np.rint(meshed.vertex_pixel[~front]).astype(int), np.flatnonzero(~front))}
    sources = warped.source_coords[front_pixels[:, 1], front_pixels[:, 0]]
    landmarks = {}
    for name, position in renders.landmarks.items():
        nearest = int(np.argmin(np.sum((sources - renders.world_to_pixel(position[:2])) ** 2, axis=1)))
        col, row = front_pixels[nearest]
        front_z = vertices[front_index[nearest], 2]
        back_z = vertices[back_of[(col, row)], 2]
        z = float(np.clip(position[2] * relative_scale[row, col], back_z, front_z))
        landmarks[name] = np.array([(col + 0.5) * pixel_size, -(row + 0.5) * pixel_size, z])
    return landmarks


def _rule(registries: list[dict[str, Callable]], name: str, setting: str) -> Callable:
    merged: dict[str, Callable] = {}
    for registry in registries:
        merged.update(registry)
    if name not in merged:
        raise UnknownFamilyError(f"unknown {setting} rule {name!r} (known: {', '.join(sorted(merged))})")
    return merged[name]


def _touches_border(mask: np.ndarray) -> bool:
    return bool(mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any())


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    return value
