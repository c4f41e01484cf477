"""Template renders: geometry of the maps, and the disk cache around them."""

from __future__ import annotations

import logging

import numpy as np
import pytest
import trimesh

import frontal3d.render as render
from frontal3d.family import Template
from frontal3d.render import cache_path_for, load_or_render, render_template


def _template(mesh: trimesh.Trimesh, face_regions=None, names=("body",), landmarks=None) -> Template:
    regions = np.zeros(len(mesh.faces), dtype=np.int32) if face_regions is None else face_regions
    return Template("testfam", "plain", mesh, regions, tuple(names), landmarks or {})


def _box(extents, center=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=extents, transform=trimesh.transformations.translation_matrix(center))


def _two_part_template() -> Template:
    """A left box labelled 'left' and a right box labelled 'right', side by side."""
    left = _box((0.3, 0.5, 0.1), (-0.2, 0.0, 0.0))
    right = _box((0.3, 0.5, 0.1), (0.2, 0.0, 0.0))
    mesh = trimesh.util.concatenate([left, right])
    labels = np.repeat([0, 1], [len(left.faces), len(right.faces)])
    return _template(mesh, labels, ("left", "right"), {"pin": (0.0, 0.25, 0.05)})


def test_renders_are_deterministic():
    template = _two_part_template()
    first, second = render_template(template, 96), render_template(template, 96)
    for name in ("mask", "front_depth", "back_depth", "front_normals", "back_normals", "front_regions", "back_regions"):
        np.testing.assert_array_equal(getattr(first, name), getattr(second, name), err_msg=name)
    assert (first.center, first.half_width) == (second.center, second.half_width)


def test_front_and_back_share_one_silhouette():
    mesh = trimesh.creation.torus(0.3, 0.1)  # a hole through the middle: the silhouette is not convex
    renders = render_template(_template(mesh), 128)
    assert renders.mask.any() and not renders.mask[64, 64]
    for depth in (renders.front_depth, renders.back_depth):
        np.testing.assert_array_equal(np.isfinite(depth), renders.mask)
    for regions in (renders.front_regions, renders.back_regions):
        np.testing.assert_array_equal(regions >= 0, renders.mask)
    for normals in (renders.front_normals, renders.back_normals):
        np.testing.assert_array_equal(np.linalg.norm(normals, axis=-1) > 0.5, renders.mask)


def test_box_depth_and_footprint_match_its_extents():
    extents, center = np.array([0.4, 0.6, 0.2]), np.array([0.1, -0.05, 0.03])
    renders = render_template(_template(_box(extents, center)), 128, margin=0.05)
    half_pixel = renders.pixel_size / 2
    # grid: centred on the XY box, the longest XY extent spans 90% of the frame
    np.testing.assert_allclose(renders.center, center[:2], atol=1e-12)
    assert renders.half_width == pytest.approx(0.6 / 2 / 0.9)
    front, back = renders.front_depth[renders.mask], renders.back_depth[renders.mask]
    np.testing.assert_allclose(front, center[2] + extents[2] / 2, atol=half_pixel)
    np.testing.assert_allclose(back, center[2] - extents[2] / 2, atol=half_pixel)
    rows, cols = np.nonzero(renders.mask)
    corners = renders.pixel_to_world(np.array([[cols.min(), rows.max()], [cols.max(), rows.min()]], dtype=float))
    np.testing.assert_allclose(corners[0], center[:2] - extents[:2] / 2, atol=renders.pixel_size)
    np.testing.assert_allclose(corners[1], center[:2] + extents[:2] / 2, atol=renders.pixel_size)


@pytest.mark.parametrize("inverted", [False, True], ids=["outward-winding", "inward-winding"])
def test_sphere_normals_point_outward(inverted):
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=0.5)
    if inverted:
        mesh.invert()
    renders = render_template(_template(mesh), 96)
    inside = renders.mask
    assert (renders.front_normals[inside][:, 2] > 0).all()
    assert (renders.back_normals[inside][:, 2] < 0).all()
    rows, cols = np.nonzero(inside)
    xy = renders.pixel_to_world(np.stack([cols, rows], axis=-1).astype(float))
    for normals, depth in ((renders.front_normals, renders.front_depth), (renders.back_normals, renders.back_depth)):
        radial = np.column_stack([xy, depth[inside]])
        radial /= np.linalg.norm(radial, axis=-1, keepdims=True)
        cosine = np.sum(radial * normals[inside], axis=-1)
        assert np.median(cosine) > 0.999 and cosine.min() > 0.95


def test_region_maps_follow_face_labels():
    renders = render_template(_two_part_template(), 128)
    assert renders.region_names == ("left", "right")
    np.testing.assert_array_equal(renders.landmarks["pin"], [0.0, 0.25, 0.05])
    rows, cols = np.nonzero(renders.mask)
    x = renders.pixel_to_world(np.stack([cols, rows], axis=-1).astype(float))[:, 0]
    for regions in (renders.front_regions, renders.back_regions):
        np.testing.assert_array_equal(regions[rows, cols], (x > 0).astype(int))


def test_back_render_is_the_far_surface():
    """Two slabs stacked along Z: the front sees only the near one, the back only the far one."""
    near, far = _box((0.4, 0.4, 0.1), (0, 0, 0.05)), _box((0.4, 0.4, 0.1), (0, 0, -0.05))
    labels = np.repeat([0, 1], [len(near.faces), len(far.faces)])
    renders = render_template(_template(trimesh.util.concatenate([near, far]), labels, ("near", "far")), 64)
    assert (renders.front_regions[renders.mask] == 0).all()
    assert (renders.back_regions[renders.mask] == 1).all()
    np.testing.assert_allclose(renders.front_depth[renders.mask], 0.1, atol=1e-5)
    np.testing.assert_allclose(renders.back_depth[renders.mask], -0.1, atol=1e-5)


@pytest.fixture
def counted_renders(monkeypatch):
    """Count calls to the real renderer, so a test can tell a cache hit from a re-render."""
    calls = []
    real = render.render_template

    def counting(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(render, "render_template", counting)
    return calls


def _assert_same_renders(a, b):
    for name in ("mask", "front_depth", "back_depth", "front_normals", "back_normals", "front_regions", "back_regions"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert (a.center, a.half_width, a.region_names) == (b.center, b.half_width, b.region_names)
    assert a.landmarks.keys() == b.landmarks.keys()


def test_second_call_hits_the_cache(tmp_path, counted_renders):
    template = _two_part_template()
    first = load_or_render(template, 64, tmp_path)
    path = cache_path_for(template, 64, cache_dir=tmp_path)
    assert path.is_file() and len(counted_renders) == 1
    second = load_or_render(template, 64, tmp_path)
    assert len(counted_renders) == 1
    _assert_same_renders(first, second)
    assert list(tmp_path.iterdir()) == [path]  # no temporary files left behind


def test_cache_key_changes_with_the_template(tmp_path):
    template = _two_part_template()
    relabelled = _template(template.mesh, 1 - template.face_regions, template.region_names, template.landmarks)
    paths = {
        cache_path_for(template, 64, cache_dir=tmp_path),
        cache_path_for(template, 96, cache_dir=tmp_path),
        cache_path_for(template, 64, margin=0.1, cache_dir=tmp_path),
        cache_path_for(relabelled, 64, cache_dir=tmp_path),
    }
    assert len(paths) == 4


def _wrong_shape_entry(path):
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    arrays["front_depth"] = arrays["front_depth"][:-1]
    with open(path, "wb") as stream:
        np.savez(stream, **arrays)


@pytest.mark.parametrize(
    "corrupt",
    [
        lambda p: p.write_bytes(b"not a zip file"),
        lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
        _wrong_shape_entry,
    ],
    ids=["garbage", "truncated", "wrong-shape"],
)
def test_corrupt_entry_is_rebuilt_with_a_warning(tmp_path, counted_renders, caplog, corrupt):
    template = _two_part_template()
    original = load_or_render(template, 64, tmp_path)
    path = cache_path_for(template, 64, cache_dir=tmp_path)
    corrupt(path)
    with caplog.at_level(logging.WARNING, logger="frontal3d.render"):
        rebuilt = load_or_render(template, 64, tmp_path)
    assert len(counted_renders) == 2
    assert any("re-rendering" in record.getMessage() for record in caplog.records)
    _assert_same_renders(original, rebuilt)
    load_or_render(template, 64, tmp_path)  # the rebuilt entry is valid again
    assert len(counted_renders) == 2


def test_default_cache_dir_comes_from_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("FRONTAL3D_CACHE_DIR", str(tmp_path / "renders"))
    template = _two_part_template()
    load_or_render(template, 32)
    assert cache_path_for(template, 32).parent == tmp_path / "renders"
    assert cache_path_for(template, 32).is_file()
