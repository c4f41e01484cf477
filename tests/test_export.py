"""Export: a GLB/OBJ a 3D tool reloads with its texture and named landmarks, written atomically."""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pygltflib
import pytest
import trimesh
from PIL import Image

import frontal3d.stages.export as export_module
from frontal3d.errors import TemplateError
from frontal3d.stages.export import export_all
from frontal3d.stages.mesh import build_mesh
from frontal3d.stages.texture import build_textured_mesh

VALIDATOR = Path(__file__).resolve().parents[1] / "tools" / "gltf-validator"
LANDMARKS = {"strap_pin": np.array([0.1, -0.3, 0.0]), "nut": np.array([0.15, -0.02, 0.04])}


@pytest.fixture(scope="module")
def textured():
    """A 20 x 16 px slab textured from a 2x photo with a colour gradient."""
    work_mask = np.zeros((24, 20), bool)
    work_mask[2:22, 2:18] = True
    mesh_result = build_mesh(work_mask, np.where(work_mask, 0.02, np.nan), np.where(work_mask, -0.02, np.nan),
                             0.01, smooth_iterations=0)
    mask = np.kron(work_mask, np.ones((2, 2), bool))
    rows, cols = np.mgrid[: mask.shape[0], : mask.shape[1]]
    image = np.stack([cols * 6, rows * 5, np.full_like(rows, 90)], axis=-1).astype(np.uint8)
    region_map = np.where(mask, 0, -1)
    return build_textured_mesh(mesh_result, image, mask, region_map, np.zeros_like(mask), ("body",),
                               "mirror_front", None, working_to_full=2)


def test_glb_reloads_with_texture_and_named_landmarks(tmp_path, textured):
    paths = export_all(tmp_path / "guitar", textured, LANDMARKS, {"family": "guitar"})
    scene = trimesh.load(paths["glb"])
    geometry = next(iter(scene.geometry.values()))
    assert isinstance(geometry.visual, trimesh.visual.TextureVisuals)
    texture = geometry.visual.material.baseColorTexture
    assert texture.size == (textured.atlas.shape[1], textured.atlas.shape[0])
    for name, position in LANDMARKS.items():
        transform, _ = scene.graph[name]
        np.testing.assert_allclose(transform[:3, 3], position, atol=1e-6)
    gltf = pygltflib.GLTF2.load(str(paths["glb"]))
    material = gltf.materials[0]
    assert material.pbrMetallicRoughness.baseColorTexture is not None
    assert material.normalTexture is not None


def test_glb_embeds_the_same_png_files_as_the_obj(tmp_path, textured):
    paths = export_all(tmp_path / "model", textured, LANDMARKS, {}, preview_size=None)
    gltf = pygltflib.GLTF2.load(str(paths["glb"]))
    blob = gltf.binary_blob()

    def embedded(texture_index: int) -> bytes:
        view = gltf.bufferViews[gltf.images[gltf.textures[texture_index].source].bufferView]
        return blob[view.byteOffset:view.byteOffset + view.byteLength]

    material = gltf.materials[0]
    assert embedded(material.pbrMetallicRoughness.baseColorTexture.index) == paths["texture"].read_bytes()
    assert embedded(material.normalTexture.index) == paths["normal"].read_bytes()
    np.testing.assert_array_equal(np.asarray(Image.open(paths["texture"])), textured.atlas)
    np.testing.assert_array_equal(np.asarray(Image.open(paths["normal"])), textured.normal_map)
    reloaded = next(iter(trimesh.load(paths["glb"]).geometry.values()))
    np.testing.assert_allclose(reloaded.vertices, textured.mesh.vertices, atol=1e-6)
    # the model in memory keeps its own textures
    assert textured.mesh.visual.material.baseColorTexture.size == (textured.atlas.shape[1], textured.atlas.shape[0])


def test_obj_mtl_textures_and_report_are_written(tmp_path, textured):
    report = {"seconds": np.float32(1.25), "size_m": np.array([0.1, 0.2, 0.04])}
    paths = export_all(tmp_path / "out", textured, LANDMARKS, report, preview_size=64)
    obj = trimesh.load(paths["obj"])
    assert obj.visual.uv.shape[0] == len(obj.vertices)
    assert "map_Kd texture.png" in paths["mtl"].read_text()
    assert paths["normal"].exists() and paths["preview"].exists()
    assert json.loads(paths["report"].read_text()) == {"seconds": 1.25, "size_m": [0.1, 0.2, 0.04]}
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(p.name for p in paths.values())


def test_debug_maps_are_written_as_pictures(tmp_path, textured):
    maps = {"mask": np.ones((4, 4), bool), "regions": np.array([[-1, 0], [1, 2]]), "depth": np.array([[np.nan, 1.0]])}
    paths = export_all(tmp_path / "out", textured, {}, {}, debug_maps=maps, preview_size=None)
    assert sorted(p.name for p in paths["debug"].iterdir()) == ["depth.png", "mask.png", "regions.png"]


def _failing_obj_writer(_):
    raise RuntimeError("disk full")


def test_failure_leaves_no_partial_folder(tmp_path, textured, monkeypatch):
    monkeypatch.setattr(export_module, "_obj_text", _failing_obj_writer)
    with pytest.raises(RuntimeError, match="disk full"):
        export_all(tmp_path / "model", textured, LANDMARKS, {})
    assert list(tmp_path.iterdir()) == []


def test_existing_folder_keeps_its_other_files_and_survives_a_failure(tmp_path, textured, monkeypatch):
    out = tmp_path / "model"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    export_all(out, textured, LANDMARKS, {"run": 1}, preview_size=None)
    assert (out / "notes.txt").read_text() == "mine"
    monkeypatch.setattr(export_module, "_obj_text", _failing_obj_writer)
    with pytest.raises(RuntimeError, match="disk full"):
        export_all(out, textured, LANDMARKS, {"run": 2}, preview_size=None)
    assert json.loads((out / "report.json").read_text()) == {"run": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model"]


def test_bad_landmark_is_rejected(tmp_path, textured):
    with pytest.raises(TemplateError, match="landmark 'nut'"):
        export_all(tmp_path / "m", textured, {"nut": np.array([0.0, np.nan, 0.0])}, {})


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
@pytest.mark.skipif(not (VALIDATOR / "node_modules" / "gltf-validator").is_dir(),
                    reason="run `npm install` in tools/gltf-validator to get the Khronos glTF validator")
def test_khronos_validator_reports_no_errors(tmp_path, textured):
    paths = export_all(tmp_path / "model", textured, LANDMARKS, {}, preview_size=None)
    run = subprocess.run(["node", str(VALIDATOR / "validate.mjs"), str(paths["glb"])],
                         capture_output=True, text=True, timeout=60)
    report = json.loads(run.stdout)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]
