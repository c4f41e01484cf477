"""Training-free classifier chain: frontal gate and subtype choice by silhouette agreement."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import trimesh

from frontal3d.family import Family, Template
from frontal3d.render import TemplateRenders, render_template
from frontal3d.stages.align import Similarity, placed_off_grid, warp_mask
from frontal3d.stages.classify import ClassifierContext, FrontalGate, SubtypeClassifier, foreshortening, silhouette_agreement

FAMILY = Family(name="guitar", subtypes=("classical", "electric"), canonical_view="front",
                regions={"classical": ("body", "hole"), "electric": ("body",)},
                real_size={"classical": 1.0, "electric": 1.0},
                view_hint="a front view of the guitar's face")
SETTINGS = {"max_angle_deg": 180.0, "frontal_threshold": 0.45}


def _guitar_like_mesh() -> trimesh.Trimesh:
    """An electric-guitar-like slab: elliptic body (0.4 x 0.5 x 0.05 m) with a neck box above it."""
    body = trimesh.creation.cylinder(radius=0.5, height=0.05, sections=64)
    body.apply_scale([0.4, 0.5, 1.0])
    body.apply_translation([0.0, -0.25, 0.0])
    neck = trimesh.creation.box(extents=[0.06, 0.55, 0.04])
    neck.apply_translation([0.0, 0.27, 0.0])
    return trimesh.util.concatenate([body, neck])


def _render(mesh: trimesh.Trimesh, yaw_deg: float = 0.0) -> TemplateRenders:
    mesh = mesh.copy()
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.deg2rad(yaw_deg), [0, 1, 0]))
    template = Template("guitar", "electric", mesh, np.zeros(len(mesh.faces)), ("body",))
    return render_template(template, 160)


def _renders_from_masks(mask: np.ndarray, regions: np.ndarray, names: tuple[str, ...]) -> TemplateRenders:
    """Flat-depth renders made straight from 2D maps, enough for the silhouette classifiers."""
    depth = np.where(mask, 0.01, np.nan).astype(np.float32)
    normals = np.zeros(mask.shape + (3,), np.float32)
    normals[mask, 2] = 1.0
    return TemplateRenders((0.0, 0.0), 0.5, mask, depth, -depth, normals, -normals, regions, regions, names)


def _context(object_mask: np.ndarray, renders: dict[str, TemplateRenders], image: np.ndarray | None = None) -> ClassifierContext:
    if image is None:
        image = np.where(object_mask[..., None], 160, 230).astype(np.uint8).repeat(3, axis=2)
    return ClassifierContext(image=image, object_mask=object_mask, family=FAMILY, renders=renders, settings=SETTINGS)


def _placed(mask: np.ndarray, shape: tuple[int, int], scale: float, angle_deg: float) -> np.ndarray:
    """``mask`` scaled, turned in the image plane and centred in a ``shape`` image."""
    centre = ((mask.shape[1] - 1) / 2, (mask.shape[0] - 1) / 2)
    matrix = cv2.getRotationMatrix2D(centre, angle_deg, scale)
    matrix[:, 2] += ((shape[1] - 1) / 2 - centre[0], (shape[0] - 1) / 2 - centre[1])
    return cv2.warpAffine(mask.astype(np.uint8), matrix, (shape[1], shape[0]), flags=cv2.INTER_NEAREST) > 0


@pytest.fixture(scope="module")
def guitar_like() -> dict[str, TemplateRenders]:
    mesh = _guitar_like_mesh()
    return {"frontal": _render(mesh), "turned": _render(mesh, 60.0)}


def test_gate_accepts_a_frontal_view_even_scaled_and_tilted(guitar_like):
    template = {"electric": guitar_like["frontal"]}
    photo = _placed(guitar_like["frontal"].mask, (300, 260), 1.6, 25.0)
    decision = FrontalGate().classify(_context(photo, template))
    assert decision.accepted and decision.label == "frontal"
    assert decision.confidence > 0.9


def test_gate_rejects_the_same_object_turned_60_degrees_with_a_reason(guitar_like):
    template = {"electric": guitar_like["frontal"]}
    photo = _placed(guitar_like["turned"].mask, (300, 260), 1.6, 0.0)
    decision = FrontalGate().classify(_context(photo, template))
    assert not decision.accepted
    assert "guitar" in decision.reason and "front view" in decision.reason and "<" in decision.reason


def test_agreement_similarity_places_the_template_on_the_object(guitar_like):
    render = guitar_like["frontal"]
    photo = _placed(render.mask, (320, 280), 1.5, 0.0)
    agreement = silhouette_agreement(photo, {"electric": render}, np.pi)["electric"]
    assert agreement.iou > 0.9
    assert agreement.similarity.scale == pytest.approx(1.5, rel=0.05)
    landed = cv2.warpAffine(render.mask.astype(np.uint8), agreement.similarity.matrix, (280, 320), flags=cv2.INTER_NEAREST) > 0
    assert (landed & photo).sum() / (landed | photo).sum() > 0.9


def test_agreement_counts_the_template_placed_past_the_grid_as_missed(guitar_like):
    """A body with no neck: with ``past_box`` the template's neck, placed off the object's box, is object not seen."""
    render = guitar_like["frontal"]
    widths = render.mask.sum(axis=1)
    body = render.mask.copy()
    body[: np.nonzero(widths > 0.5 * widths.max())[0].min() - 2] = False
    photo = _placed(body, (300, 260), 1.5, 0.0)
    counted = silhouette_agreement(photo, {"electric": render}, np.pi, past_box=True)["electric"]
    assert counted.iou == pytest.approx(body.sum() / render.mask.sum(), abs=0.04)
    assert silhouette_agreement(photo, {"electric": render}, np.pi)["electric"].iou > counted.iou + 0.1


def test_placed_off_grid_counts_the_pixels_warp_mask_drops():
    square = np.ones((10, 10), bool)
    assert placed_off_grid(square, Similarity(1.0, 0.0, 2.0, 3.0), (20, 20)) == 0
    assert placed_off_grid(square, Similarity(1.0, 0.0, -5.0, 0.0), (20, 20)) == 50
    turned = Similarity(2.0, np.pi / 4, 15.0, -8.0)
    canvas = warp_mask(square, Similarity(1.0, 0.0, 40.0, 40.0).compose(turned), (120, 120))
    assert canvas.sum() - warp_mask(square, turned, (20, 20)).sum() == placed_off_grid(square, turned, (20, 20))


def test_subtype_picks_the_matching_one_of_two_clearly_different_shapes():
    size = 128
    disc = np.zeros((size, size), np.uint8)
    cv2.circle(disc, (64, 64), 50, 1, -1)
    bar = np.zeros((size, size), np.uint8)
    cv2.rectangle(bar, (54, 8), (74, 120), 1, -1)
    renders = {
        "round": _renders_from_masks(disc > 0, np.where(disc > 0, 0, -1).astype(np.int32), ("body",)),
        "long": _renders_from_masks(bar > 0, np.where(bar > 0, 0, -1).astype(np.int32), ("body",)),
    }
    photo = _placed(bar > 0, (240, 240), 1.7, 30.0)
    decision = SubtypeClassifier().classify(_context(photo, renders))
    assert decision.label == "long" and decision.runner_up == "round"
    assert decision.confidence > 0.9 and decision.runner_up_confidence < 0.1


def _equal_silhouettes() -> tuple[np.ndarray, dict[str, TemplateRenders], np.ndarray, tuple[int, int], int]:
    """Two templates with the same outline, one with a sound hole; a plain photo of that outline,
    and where (centre, radius) the placed template puts its hole."""
    size = 160
    body = np.zeros((size, size), np.uint8)
    cv2.ellipse(body, (80, 95), (55, 60), 0, 0, 360, 1, -1)
    cv2.rectangle(body, (74, 5), (86, 60), 1, -1)
    mask = body > 0
    hole = np.zeros_like(body)
    cv2.circle(hole, (80, 75), 16, 1, -1)
    with_hole = np.where(mask, 0, -1).astype(np.int32)
    with_hole[hole > 0] = 1
    renders = {
        "classical": _renders_from_masks(mask, with_hole, ("body", "hole")),
        "electric": _renders_from_masks(mask, np.where(mask, 0, -1).astype(np.int32), ("body",)),
    }
    photo_mask = _placed(mask, (320, 320), 1.8, 0.0)
    plain = np.where(photo_mask[..., None], np.array([190, 130, 70]), 235).astype(np.uint8)
    return photo_mask, renders, plain, (160, 160 + round(1.8 * (75 - 79.5))), round(1.8 * 16)


def test_a_dark_sound_hole_decides_between_two_equal_silhouettes():
    photo_mask, renders, plain, centre, radius = _equal_silhouettes()
    plain_top = SubtypeClassifier().classify(_context(photo_mask, renders, plain))
    assert plain_top.label == "electric" and "classical: silhouette agreement" in plain_top.reason
    assert "hole cue -0.50" in plain_top.reason  # report.json says why the tie went to electric
    holed = plain.copy()
    cv2.circle(holed, centre, radius, (25, 20, 15), -1)
    decision = SubtypeClassifier().classify(_context(photo_mask, renders, holed))
    assert decision.label == "classical" and decision.runner_up == "electric"
    assert decision.reason.startswith("classical: silhouette agreement") and "hole cue +1.00" in decision.reason


def test_a_hole_drawn_as_a_ring_counts_but_strings_across_the_spot_do_not():
    """A hole painted in the body's colour shows only its outline (a drawing, a rosette): a
    ring a little off the template's spot and larger decides for the classical template;
    strings and a bridge line over the same spot (edges that step both ways) do not."""
    photo_mask, renders, plain, (cx, cy), radius = _equal_silhouettes()
    ringed = plain.copy()
    cv2.circle(ringed, (cx + 6, cy - 5), round(1.15 * radius), (90, 60, 30), 2)
    assert SubtypeClassifier().classify(_context(photo_mask, renders, ringed)).label == "classical"
    strung = plain.copy()
    for x in range(cx - 12, cx + 13, 5):
        cv2.line(strung, (x, cy - 3 * radius), (x, cy + 3 * radius), (90, 60, 30), 1)
    cv2.line(strung, (cx - radius, cy + 2 * radius), (cx + radius, cy + 2 * radius), (90, 60, 30), 2)
    assert SubtypeClassifier().classify(_context(photo_mask, renders, strung)).label == "electric"


def test_a_hole_spot_under_an_occluder_is_no_evidence_against_the_hole():
    """The occluded pixels inside the object's outline count as object for the silhouettes, but
    they show the occluder: a sleeve over the sound hole is not a plain top. The classical
    template, a little closer to the outline, must keep its lead."""
    from frontal3d.stages.occlusion import VisibleAgreementContext

    photo_mask, renders, plain, centre, radius = _equal_silhouettes()
    slimmer = np.zeros(renders["electric"].mask.shape, np.uint8)
    cv2.ellipse(slimmer, (80, 95), (53, 60), 0, 0, 360, 1, -1)
    cv2.rectangle(slimmer, (74, 5), (86, 60), 1, -1)
    renders["electric"] = _renders_from_masks(slimmer > 0, np.where(slimmer > 0, 0, -1).astype(np.int32), ("body",))
    image = plain.copy()
    cv2.circle(image, centre, radius, (25, 20, 15), -1)
    arm = np.zeros(photo_mask.shape, np.uint8)  # a sleeve across the hole, light as a plain top
    cv2.rectangle(arm, (centre[0] - 3 * radius, centre[1] - 2 * radius), (centre[0] + 3 * radius, centre[1] + 2 * radius), 1, -1)
    image[arm > 0] = (235, 200, 180)
    fields = dict(image=image, object_mask=photo_mask, family=FAMILY, renders=renders, settings=SETTINGS)
    unaware = SubtypeClassifier().classify(VisibleAgreementContext(**fields, hidden=None))
    assert unaware.label == "electric"  # read as a plain top, the hole spot outweighs the silhouettes
    decision = SubtypeClassifier().classify(VisibleAgreementContext(**fields, hidden=arm > 0))
    assert decision.label == "classical" and decision.runner_up == "electric"


@pytest.mark.parametrize("subtype", ["classical", "electric"])
def test_the_chain_rejects_a_side_on_guitar_and_says_which_view_it_needs(subtype):
    import frontal3d
    from frontal3d.errors import NotFrontalError
    from frontal3d.photo_render import frontal_camera, render_frontal
    from frontal3d.plugins import Plugins

    plugins = Plugins()
    family = plugins.family("guitar")
    mesh = plugins.hook.frontal3d_template(family=family, subtype=subtype, settings=plugins.settings("guitar")).mesh.copy()
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.deg2rad(80.0), [0, 1, 0]))
    rgba = render_frontal(mesh, frontal_camera(mesh, 256, 0.8))
    with pytest.raises(NotFrontalError, match="front view of the guitar's face"):
        frontal3d.reconstruct(rgba, "guitar", plugins=plugins, template_resolution=128, working_resolution=128)


@pytest.mark.parametrize("degrees", [0.0, 40.0])
def test_foreshortening_reads_the_squeeze_along_the_template_axis_wherever_the_template_lies(degrees):
    """A view turned by a about the template's up axis squeezes its width by cos(a); placed anywhere, any angle, any size."""
    template = np.zeros((200, 200), np.uint8)
    cv2.ellipse(template, (100, 100), (40, 80), 0, 0, 360, 1, -1)
    squeeze = np.cos(np.deg2rad(degrees))
    squeezed = cv2.warpAffine(template, np.array([[squeeze, 0, 100 * (1 - squeeze)], [0, 1, 0]]), (200, 200), flags=cv2.INTER_NEAREST) > 0
    placement = Similarity(7.5, np.deg2rad(35.0), 900.0, 400.0)  # a big photo: 2,600 x 2,400 px
    photo_mask = warp_mask(squeezed, placement, (2400, 2600))
    renders = _renders_from_masks(template > 0, template.astype(np.int32), ("body",))
    assert foreshortening(photo_mask, renders, placement) == pytest.approx(squeeze, abs=0.01)
