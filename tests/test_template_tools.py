"""User meshes as templates: labels, repairs, refusals; and the contact sheet."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from PIL import Image

from frontal3d.errors import TemplateError
from frontal3d.family import Family
from frontal3d.render import render_template
from frontal3d.template_tools import SHEET_SIZE_PX, contact_sheet, template_from_mesh

GUITAR = Family("guitar", ("electric",), "front", {"electric": ("body", "neck")}, {"electric": 1.0})
CAR = Family("car", ("sedan",), "side", {"sedan": ("body", "wheels")}, {"sedan": 4.5})


def _box(extents, center=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=extents, transform=trimesh.transformations.translation_matrix(center))


def _body_and_neck() -> tuple[trimesh.Trimesh, trimesh.Trimesh]:
    """A flat guitar-ish pair of disjoint closed boxes: a wide body and a neck above it."""
    return _box((0.35, 0.45, 0.08), (0, -0.25, 0)), _box((0.06, 0.5, 0.04), (0, 0.26, 0))


def test_open_mesh_is_repaired_with_a_warning(tmp_path):
    box = _box((0.3, 0.5, 0.1))
    box.update_faces(box.face_normals[:, 2] < 0.9)  # drop the +Z side (two triangles)
    box.remove_unreferenced_vertices()
    box.export(tmp_path / "open.ply")
    template, warnings = template_from_mesh(tmp_path / "open.ply", GUITAR, "electric")
    assert template.mesh.is_watertight
    assert template.mesh.volume == pytest.approx(0.3 * 0.5 * 0.1, rel=1e-6)
    assert any("not watertight" in w for w in warnings)
    assert len(template.face_regions) == len(template.mesh.faces)


def test_mesh_lying_along_z_is_refused_naming_the_axis(tmp_path):
    _box((0.1, 0.3, 1.0)).export(tmp_path / "lying.stl")
    with pytest.raises(TemplateError, match=r"Z is not the thinnest axis.*rotate"):
        template_from_mesh(tmp_path / "lying.stl", GUITAR, "electric")
    with pytest.raises(TemplateError, match=r"Z is the longest axis.*rotate"):
        template_from_mesh(tmp_path / "lying.stl", CAR, "sedan")


def _expected_labels(template) -> np.ndarray:
    """Neck faces are the ones above y = 0 (body ends at y = -0.025, neck starts at y = 0.01)."""
    return (template.mesh.triangles_center[:, 1] > 0.0).astype(np.int32)


def test_regions_from_vertex_colours(tmp_path):
    body, neck = _body_and_neck()
    body.visual.vertex_colors = np.tile([200, 30, 30, 255], (len(body.vertices), 1))
    neck.visual.vertex_colors = np.tile([30, 200, 30, 255], (len(neck.vertices), 1))
    trimesh.util.concatenate([body, neck]).export(tmp_path / "coloured.ply")
    mapping = {"#c81e1e": "body", "#1ec81e": "neck"}
    template, _ = template_from_mesh(tmp_path / "coloured.ply", GUITAR, "electric", regions=mapping)
    np.testing.assert_array_equal(template.face_regions, _expected_labels(template))
    with pytest.raises(TemplateError, match="#1ec81e"):
        template_from_mesh(tmp_path / "coloured.ply", GUITAR, "electric", regions={"#c81e1e": "body"})


def test_regions_from_scene_geometry_names(tmp_path):
    body, neck = _body_and_neck()
    scene = trimesh.Scene()
    scene.add_geometry(body, geom_name="Body")
    scene.add_geometry(neck, geom_name="neck")
    scene.export(tmp_path / "parts.glb")
    template, warnings = template_from_mesh(tmp_path / "parts.glb", GUITAR, "electric")
    assert template.region_names == ("body", "neck") and template.mesh.is_watertight
    np.testing.assert_array_equal(template.face_regions, _expected_labels(template))
    assert warnings == []


def test_unknown_group_names_are_listed(tmp_path):
    body, neck = _body_and_neck()
    scene = trimesh.Scene()
    scene.add_geometry(body, geom_name="Cube")
    scene.add_geometry(neck, geom_name="Cube.001")
    scene.export(tmp_path / "unnamed.glb")
    with pytest.raises(TemplateError, match=r"Cube.*Cube\.001.*regions=") as error:
        template_from_mesh(tmp_path / "unnamed.glb", GUITAR, "electric")
    assert "\n" not in str(error.value)
    template, _ = template_from_mesh(
        tmp_path / "unnamed.glb", GUITAR, "electric", regions={"Cube": "body", "Cube.001": "neck"}
    )
    np.testing.assert_array_equal(template.face_regions, _expected_labels(template))


def test_contact_sheet_writes_a_png_of_the_expected_size(tmp_path):
    body, neck = _body_and_neck()
    scene = trimesh.Scene()
    scene.add_geometry(body, geom_name="body")
    scene.add_geometry(neck, geom_name="neck")
    scene.export(tmp_path / "parts.glb")
    template, _ = template_from_mesh(tmp_path / "parts.glb", GUITAR, "electric")
    template.landmarks = {"strap_pin": np.array([0.0, -0.47, 0.0])}
    out = tmp_path / "sheet" / "template.png"
    contact_sheet(template, render_template(template, 96), out)
    with Image.open(out) as image:
        assert image.size == SHEET_SIZE_PX
        pixels = np.asarray(image.convert("L"))
    assert pixels.std() > 10  # not a blank canvas
