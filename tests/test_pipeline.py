"""The whole pipeline as a user runs it: photo in, watertight textured mesh and report out."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

import frontal3d
from frontal3d.cli import main
from frontal3d.errors import NotFrontalError
from frontal3d.evaluate import voxel_iou
from frontal3d.photo_render import frontal_camera, render_frontal
from frontal3d.plugins import Plugins
from frontal3d.stages import align
from frontal3d.stages.align import Similarity

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "sportscar.png"


@pytest.fixture(scope="module")
def plugins() -> Plugins:
    return Plugins()


def _template_photo(plugins: Plugins, family: str, subtype: str, rotate_y_deg: float = 0.0, resolution: int = 320):
    """A render of a built-in template, coloured by region, as the input photo."""
    fam = plugins.family(family)
    template = plugins.hook.frontal3d_template(family=fam, subtype=subtype, settings=plugins.settings(family))
    mesh = template.mesh.copy()
    palette = np.array([[200, 60, 40, 255], [40, 40, 60, 255], [30, 30, 30, 255], [230, 200, 60, 255], [90, 160, 90, 255], [60, 90, 200, 255]], np.uint8)
    mesh.visual = trimesh.visual.ColorVisuals(mesh, face_colors=palette[template.face_regions % len(palette)])
    if rotate_y_deg:
        mesh.apply_transform(trimesh.transformations.rotation_matrix(np.deg2rad(rotate_y_deg), [0, 1, 0]))
    rgba = render_frontal(mesh, frontal_camera(mesh, resolution, 0.8))
    return rgba, template


def _silhouette(mesh: trimesh.Trimesh, like: np.ndarray) -> np.ndarray:
    """The mesh's frontal silhouette, rendered on a grid fitted to its own bounds."""
    return render_frontal(mesh, frontal_camera(mesh, max(like.shape), 0.8))[..., 3] > 0


def test_template_reconstructed_from_its_own_render_matches_itself(plugins):
    rgba, template = _template_photo(plugins, "car", "sedan")
    result = frontal3d.reconstruct(rgba, "car", subtype="sedan", plugins=plugins)
    assert result.mesh.is_watertight and result.mesh.is_winding_consistent and result.mesh.volume > 0
    assert voxel_iou(result.mesh, template.mesh) > 0.9
    assert result.report["subtype"] == "sedan"
    assert result.report["segmenter"] == "alpha channel"


def test_silhouette_of_the_mesh_matches_the_input_mask(plugins):
    rgba, _ = _template_photo(plugins, "guitar", "electric")
    result = frontal3d.reconstruct(rgba, "guitar", plugins=plugins)
    mask = rgba[..., 3] > 0
    ys, xs = np.nonzero(mask)
    cropped = mask[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    rendered = _silhouette(result.mesh, cropped)
    ys, xs = np.nonzero(rendered)
    rendered = rendered[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    import cv2

    rendered = cv2.resize(rendered.astype(np.uint8), cropped.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
    iou = (rendered & cropped).sum() / (rendered | cropped).sum()
    assert iou > 0.95
    assert result.report["subtype"] == "electric"


@pytest.mark.parametrize("scale, expected_source", [(1.3, "classifier"), (1.01, "mutual information")])
def test_an_alignment_gone_astray_gives_way_to_the_classifiers_placement(plugins, monkeypatch, scale, expected_source):
    """Mutual information weighs the photo's grey image and can end far off the outline (a
    sunburst guitar photo: outline IoU 0.73 against the classifier's 0.82): then the classifier's
    placement stands; a placement within ``MI_OUTLINE_SLACK`` of it is kept."""
    rgba, _ = _template_photo(plugins, "guitar", "electric")
    clean = frontal3d.reconstruct(rgba, "guitar", plugins=plugins)
    real_align = align.align_template

    def pushed_off(*args, **kwargs):
        placed, diagnostics = real_align(*args, **kwargs)
        return Similarity(placed.scale * scale, placed.angle, placed.tx, placed.ty), diagnostics

    monkeypatch.setattr(align, "align_template", pushed_off)
    result = frontal3d.reconstruct(rgba, "guitar", plugins=plugins)
    assert result.report["alignment"]["source"].startswith(expected_source)
    assert result.report["mesh"]["size_m"] == pytest.approx(clean.report["mesh"]["size_m"], rel=0.03)


def test_mask_with_a_hole_and_a_separate_blob(plugins):
    """A frame-shaped object (hole in the mask) plus a far-away object: closed mesh of the largest."""
    image = np.full((300, 400, 3), 235, np.uint8)
    mask = np.zeros((300, 400), bool)
    mask[40:160, 20:240] = True
    mask[70:130, 70:210] = False  # the hole
    mask[220:295, 300:395] = True  # a separate object, far away
    image[mask] = (150, 40, 40)
    result = frontal3d.reconstruct(image, "car", mask=mask, subtype="sedan", plugins=plugins, frontal_threshold=0.0)
    assert result.mesh.is_watertight
    assert result.mesh.euler_number == 0  # one through-hole: genus 1
    assert any("2 separate objects" in w for w in result.report["warnings"])
    assert not any("touches the image border" in w for w in result.report["warnings"])


def test_a_hole_the_segmenter_leaves_in_a_solid_part_is_filled(plugins):
    """A chrome hub or a window of the backdrop's colour: the segmenter leaves a hole the car's
    template does not have, and the model would be see-through there. A mask the user gives
    keeps its hole (a frame's opening, above)."""
    import cv2

    rgba = np.asarray(cv2.imread(str(EXAMPLE), cv2.IMREAD_UNCHANGED))[..., [2, 1, 0, 3]]
    car = rgba[..., 3] > 127
    ys, xs = np.nonzero(car)
    backdrop = (245, 245, 245)
    image = np.full(car.shape + (3,), backdrop, np.uint8)
    image[car] = rgba[..., :3][car]
    centre, radius = (int(xs.min() + 0.45 * np.ptp(xs)), int(ys.min() + 0.55 * np.ptp(ys))), int(0.04 * np.ptp(xs))
    cv2.circle(image, centre, radius, backdrop, -1)  # in the door, the backdrop's colour
    holed = car.astype(np.uint8)
    cv2.circle(holed, centre, radius, 0, -1)

    found = frontal3d.reconstruct(image, "car", plugins=plugins)
    given = frontal3d.reconstruct(image, "car", mask=holed > 0, plugins=plugins)
    left_open = frontal3d.reconstruct(image, "car", plugins=plugins, fill_holes=False)

    working_radius = radius * found.report["working_size"][0] / found.report["crop"]["width"]
    assert found.report["filled_hole_pixels"] > 0.5 * np.pi * working_radius**2
    assert found.mesh.is_watertight and found.mesh.euler_number == 2  # solid: no hole through the door
    assert "filled_hole_pixels" not in given.report and given.mesh.euler_number == 0  # the user's hole stays
    assert "filled_hole_pixels" not in left_open.report and left_open.mesh.euler_number == 0  # fill_holes = false


def _side_by_side(*rgbas: np.ndarray, gap: int = 100) -> np.ndarray:
    """RGBA renders placed left to right on one transparent canvas, far enough apart to stay separate objects."""
    height = max(rgba.shape[0] for rgba in rgbas)
    canvas = np.zeros((height, sum(rgba.shape[1] for rgba in rgbas) + gap * (len(rgbas) - 1), 4), np.uint8)
    left = 0
    for rgba in rgbas:
        canvas[: rgba.shape[0], left : left + rgba.shape[1]] = rgba
        left += rgba.shape[1] + gap
    return canvas


def test_all_reconstructs_each_separate_object_largest_first(plugins, tmp_path):
    import cv2

    big, _ = _template_photo(plugins, "car", "sedan")
    small = cv2.resize(big, None, fx=0.7, fy=0.7, interpolation=cv2.INTER_NEAREST)
    photo = _side_by_side(small, big)
    results = frontal3d.reconstruct_all(photo, "car", subtype="sedan", plugins=plugins)
    assert [r.report["objects"]["rank"] for r in results] == [1, 2]
    assert all(r.mesh.is_watertight for r in results)
    pixels = [int(w.split("(")[-1].split()[0]) for r in results for w in r.report["warnings"] if "separate objects" in w]
    assert pixels[0] == pytest.approx((big[..., 3] > 0).sum(), rel=0.05)
    assert pixels[1] == pytest.approx((small[..., 3] > 0).sum(), rel=0.05)
    # the CLI writes one folder per object, and only the largest without --all
    image = tmp_path / "two_cars.png"
    cv2.imwrite(str(image), cv2.cvtColor(photo, cv2.COLOR_RGBA2BGRA))
    assert main(["reconstruct", str(image), "--family", "car", "--subtype", "sedan", "--all", "-o", str(tmp_path / "all")]) == 0
    assert sorted(p.name for p in (tmp_path / "all").iterdir()) == ["two_cars_1", "two_cars_2"]
    assert (tmp_path / "all" / "two_cars_2" / "model.glb").is_file()
    assert main(["reconstruct", str(image), "--family", "car", "--subtype", "sedan", "-o", str(tmp_path / "one")]) == 0
    assert sorted(p.name for p in (tmp_path / "one").iterdir()) == ["two_cars"]


def test_a_larger_object_the_chain_turns_down_gives_way_to_the_next(plugins):
    """A car seen from the front, larger than a side-on car beside it: the side-on car is reconstructed."""
    side, _ = _template_photo(plugins, "car", "sedan")
    front, _ = _template_photo(plugins, "car", "sedan", rotate_y_deg=90)  # fills its frame: 3.5 times the side view's pixels
    assert (front[..., 3] > 0).sum() > (side[..., 3] > 0).sum()
    result = frontal3d.reconstruct(_side_by_side(front, side), "car", plugins=plugins)
    objects = result.report["objects"]
    assert objects["found"] == 2 and objects["rank"] == 2
    assert "side view" in objects["turned_down"][0]["reason"]
    assert any("turned down by the classifier chain" in w for w in result.report["warnings"])
    assert result.mesh.is_watertight
    with pytest.raises(NotFrontalError, match="side view"):
        frontal3d.reconstruct(front, "car", plugins=plugins)


def test_side_on_view_is_rejected_with_a_reason(plugins):
    rgba, _ = _template_photo(plugins, "car", "sedan", rotate_y_deg=90)
    with pytest.raises(NotFrontalError, match="side view") as given:
        frontal3d.reconstruct(rgba, "car", plugins=plugins)
    assert "--mask" not in str(given.value)  # the alpha channel's outline is the object's


def test_a_turned_down_outline_the_segmenter_found_points_to_mask(plugins):
    """The chain judges the segmenter's outline; when that is wrong (a kerb taken in), the
    reason alone would blame the view: the message says a mask can be given."""
    rgba, _ = _template_photo(plugins, "car", "sedan", rotate_y_deg=90)
    car = rgba[..., 3] > 0
    photo = np.full(car.shape + (3,), 235, np.uint8)
    photo[car] = rgba[..., :3][car]
    with pytest.raises(NotFrontalError, match="side view") as found:
        frontal3d.reconstruct(photo, "car", plugins=plugins)
    message = str(found.value)
    assert "segmenter's" in message and "--mask" in message and "\n" not in message


def test_verbose_pictures_the_outline_a_turned_down_photo_was_judged_by(plugins, tmp_path, capsys):
    """With -v the one-line error names a sheet showing the outline the chain judged: the
    photo as it is inside the outline, dimmed outside it. Without -v nothing is written."""
    import cv2

    from frontal3d.preview import OUTSIDE_BRIGHTNESS

    rgba, _ = _template_photo(plugins, "car", "sedan", rotate_y_deg=90)
    car = rgba[..., 3] > 0
    rgba[~car, :3] = 200  # a grey backdrop, which the alpha channel leaves out
    image = tmp_path / "front_on.png"
    cv2.imwrite(str(image), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
    assert main(["reconstruct", str(image), "--family", "car", "-o", str(tmp_path / "quiet")]) == 2
    assert not (tmp_path / "quiet").exists()

    out = tmp_path / "out"
    assert main(["reconstruct", str(image), "--family", "car", "-o", str(out), "-v"]) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    sheet_path = out / "front_on_turned_down.png"
    assert error.startswith("frontal3d: error: ") and "side view" in error and str(sheet_path) in error
    assert sorted(p.name for p in out.iterdir()) == [sheet_path.name]
    sheet = cv2.cvtColor(cv2.imread(str(sheet_path)), cv2.COLOR_BGR2RGB).astype(int)
    assert sheet.shape[:2] == rgba.shape[:2]
    inside = cv2.erode(car.astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    outside = cv2.dilate(car.astype(np.uint8), np.ones((7, 7), np.uint8)) == 0
    outside[:40] = False  # the label
    photo = rgba[..., :3].astype(int)
    assert np.abs(sheet[inside] - photo[inside]).max() <= 1
    assert np.abs(sheet[outside] - (photo[outside] * OUTSIDE_BRIGHTNESS).astype(int)).max() <= 1


def test_report_names_every_stage_and_decision(plugins):
    rgba, _ = _template_photo(plugins, "airplane", "airliner")
    result = frontal3d.reconstruct(rgba, "airplane", plugins=plugins)
    report = result.report
    for stage in ("segment", "classify", "align", "occlusion", "regions", "boundary", "warp", "mesh", "texture"):
        assert stage in report["stages"]
    names = [d["name"] for d in report["decisions"]]
    assert names == ["frontal", "subtype"]
    assert report["decisions"][1]["runner_up"] is not None
    assert report["mesh"]["watertight"]
    assert set(result.landmarks) == {"nose", "tail", "wing_tip_left", "wing_tip_right", "fin_tip"}
    lo, hi = result.mesh.bounds
    for position in result.landmarks.values():
        assert np.all(position >= lo - 1e-6) and np.all(position <= hi + 1e-6)


def test_cli_reconstructs_the_bundled_example(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["reconstruct", str(EXAMPLE), "--family", "auto", "--set", "size_m=4.2", "-o", str(out)]) == 0
    folder = out / "sportscar"
    for name in ("model.glb", "model.obj", "model.mtl", "texture.png", "preview.png", "report.json"):
        assert (folder / name).is_file(), name
    report = json.loads((folder / "report.json").read_text())
    assert report["family"] == "car"
    assert report["mesh"]["watertight"]
    assert max(report["mesh"]["size_m"]) == pytest.approx(4.2)
    loaded = trimesh.load(folder / "model.glb", force="scene")
    node_names = set(loaded.graph.nodes)
    assert {"wheel_front_left", "wheel_rear_right"} <= node_names
    for name in ("model.glb", "model.obj"):  # the files split vertices at texture seams only
        solid = trimesh.load(folder / name, force="mesh")
        solid.merge_vertices(merge_tex=True, merge_norm=True)
        assert solid.is_watertight and solid.volume > 0, name
    assert [p for p in tmp_path.iterdir()] == [out]  # no staging folder left behind


def _fuselage_depth_over_length(mesh: trimesh.Trimesh) -> float:
    """Depth of the mesh at its planform centre (the fuselage), over its length (Y)."""
    lo, hi = mesh.bounds
    centre, length = (lo + hi) / 2, hi[1] - lo[1]
    near = (np.abs(mesh.vertices[:, 0] - centre[0]) < 0.03 * length) & (np.abs(mesh.vertices[:, 1] - centre[1]) < 0.05 * length)
    return float(np.ptp(mesh.vertices[near, 2]) / length)


def test_length_depth_keeps_a_wide_span_plane_as_deep_as_it_is_long(plugins):
    """A plane with 60 % more span than the template, which the placement follows: with
    depth_scale=length its fuselage keeps the template's depth for its length; scaled by the
    alignment alone it comes out too deep. (At 40 % more span the best-fitting placement
    follows the length instead, and both depths come out right.)"""
    import cv2

    rgba, template = _template_photo(plugins, "airplane", "light")
    wide = cv2.resize(rgba, (int(rgba.shape[1] * 1.6), rgba.shape[0]), interpolation=cv2.INTER_NEAREST)
    expected = _fuselage_depth_over_length(template.mesh)
    by_length = frontal3d.reconstruct(wide, "airplane", subtype="light", plugins=plugins, depth_scale="length")
    by_alignment = frontal3d.reconstruct(wide, "airplane", subtype="light", plugins=plugins, depth_scale="global")
    assert _fuselage_depth_over_length(by_length.mesh) == pytest.approx(expected, rel=0.08)
    assert _fuselage_depth_over_length(by_alignment.mesh) > 1.15 * expected


class _CountingSegmentWrapper:
    """A plugin wrapping the segment hook (as a timing or logging plugin would)."""

    calls = 0

    @frontal3d.hookimpl(wrapper=True)
    def frontal3d_segment(self, image, family, settings, hints):
        type(self).calls += 1
        return (yield)


def test_a_plugin_wrapping_the_segmenter_chain_still_gets_the_mask():
    wrapped = Plugins()
    wrapped.pm.register(_CountingSegmentWrapper(), name="wrapper")
    rgba, _ = _template_photo(wrapped, "car", "sedan")
    result = frontal3d.reconstruct(rgba, "car", subtype="sedan", plugins=wrapped)
    assert _CountingSegmentWrapper.calls == 1
    assert result.report["segmenter"] == "segmenter chain (wrapped by a plugin)"
    assert result.mesh.is_watertight


def test_shape_prior_keeps_a_clean_photo_and_never_touches_a_given_mask(plugins):
    rgba, _ = _template_photo(plugins, "airplane", "fighter")
    mask = rgba[..., 3] > 0
    photo = np.where(mask[..., None], rgba[..., :3], 235).astype(np.uint8)
    result = frontal3d.reconstruct(photo, "airplane", shape_prior=True, frontal_threshold=0, weights={}, plugins=plugins)
    assert result.report["segmenter"] == "GrabCut (training-free)"  # the shape prior re-cuts the training-free segmenter's masks only
    assert result.mesh.is_watertight
    assert result.report["shape_prior_changed_pixels"] < 0.02 * mask.sum()
    given = frontal3d.reconstruct(photo, "airplane", mask=mask, shape_prior=True, frontal_threshold=0, plugins=plugins)
    assert "shape_prior_changed_pixels" not in given.report


def test_a_texture_too_large_for_game_engines_is_kept_within_max_texture_side(plugins):
    """The atlas (front and back side by side) stays within the limit, says so, and still lines up with the model."""
    full = frontal3d.reconstruct(EXAMPLE, "car", plugins=plugins)
    capped = frontal3d.reconstruct(EXAMPLE, "car", plugins=plugins, max_texture_side=301)  # odd: rounding may not pass it
    assert max(full.textured.atlas.shape[:2]) > 600  # the photo's resolution: no warning
    assert not any("max_texture_side" in w for w in full.report["warnings"])
    assert max(capped.textured.atlas.shape[:2]) <= 301
    assert any("max_texture_side = 301" in w for w in capped.report["warnings"])
    assert len(capped.mesh.vertices) == len(full.mesh.vertices)  # the same shape, only the texture is coarser
    # Same UVs on both atlases, so each vertex's colour must agree with the full texture's (the car's dark
    # wheels beside its red body would show any shift).
    colours = []
    for result in (full, capped):
        atlas, uv = result.textured.atlas, result.textured.mesh.visual.uv
        rows = np.clip(((1.0 - uv[:, 1]) * atlas.shape[0]).astype(int), 0, atlas.shape[0] - 1)
        cols = np.clip((uv[:, 0] * atlas.shape[1]).astype(int), 0, atlas.shape[1] - 1)
        colours.append(atlas[rows, cols].astype(np.float64))
    assert np.median(np.abs(colours[0] - colours[1])) < 12
