"""Export (last stage): write the textured model in the formats 3D tools read.

``model.glb`` is the main output: one PBR material with the atlas as base colour and
the derived normal map, and the landmarks as named empty child nodes of the model
node, so a VR scene can attach a strap or a wheel by name. ``model.obj`` +
``model.mtl`` + ``texture.png`` + ``normal.png`` serve tools without glTF.
Everything is written into a hidden staging folder next to ``out_dir`` and only
moved into place once complete, so a failure never leaves half a model behind.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pygltflib
import trimesh
from PIL import Image

from frontal3d.errors import InputError, TemplateError
from frontal3d.stages.texture import TexturedMesh

#: Distinct colours for label maps in the debug folder (label -1, "outside", is black).
_LABEL_PALETTE = np.array([
    [230, 25, 75], [60, 180, 75], [255, 225, 25], [0, 130, 200], [245, 130, 48],
    [145, 30, 180], [70, 240, 240], [240, 50, 230], [210, 245, 60], [250, 190, 190],
], np.uint8)


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"report value of type {type(value).__name__} is not JSON serializable")


def _encode_png(image: Image.Image) -> bytes:
    """PNG bytes of an image (zlib level 6, PIL's default)."""
    buffer = io.BytesIO()
    image.save(buffer, format="png")
    return buffer.getvalue()


def _glb_with_landmarks(textured: TexturedMesh, landmarks: dict[str, np.ndarray], texture_png: bytes,
                        normal_png: bytes) -> bytes:
    """trimesh's GLB with the given PNGs as its textures, and one named, empty child node per
    landmark under the model node.

    trimesh would encode the atlas and normal map itself, a second time (a second each on a
    phone photo's 13-megapixel atlas), so it exports 1 x 1 stand-ins whose bytes are swapped
    for the PNGs the OBJ's files hold.
    """
    source = textured.mesh
    original = source.visual.material
    # Two different stand-ins: trimesh stores equal images once, in one buffer view.
    material = trimesh.visual.material.PBRMaterial(
        name=original.name, baseColorFactor=original.baseColorFactor, metallicFactor=original.metallicFactor,
        roughnessFactor=original.roughnessFactor, baseColorTexture=Image.new("RGB", (1, 1), (0, 0, 0)),
        normalTexture=Image.new("RGB", (1, 1), (255, 255, 255)))
    stand_in = trimesh.Trimesh(vertices=source.vertices, faces=source.faces, process=False,
                               visual=trimesh.visual.TextureVisuals(uv=source.visual.uv, material=material))
    gltf = pygltflib.GLTF2.load_from_bytes(stand_in.export(file_type="glb"))
    material = gltf.materials[0]
    _swap_images(gltf, {
        gltf.textures[material.pbrMetallicRoughness.baseColorTexture.index].source: texture_png,
        gltf.textures[material.normalTexture.index].source: normal_png,
    })
    model_node = next(i for i, node in enumerate(gltf.nodes) if node.mesh is not None)
    parent = gltf.nodes[model_node]
    parent.name = parent.name or "model"
    for name, position in landmarks.items():
        gltf.nodes.append(pygltflib.Node(name=name, translation=[float(v) for v in position]))
        parent.children = [*(parent.children or []), len(gltf.nodes) - 1]
    return b"".join(gltf.save_to_bytes())


def _swap_images(gltf: pygltflib.GLTF2, encoded: dict[int, bytes]) -> None:
    """Give images (by index) new bytes: the binary buffer is laid out again, every view 4-byte aligned."""
    blob = gltf.binary_blob()
    new_bytes = {gltf.images[index].bufferView: data for index, data in encoded.items()}
    pieces, offset = [], 0
    for number, view in enumerate(gltf.bufferViews):
        start = view.byteOffset or 0
        data = new_bytes.get(number, blob[start:start + view.byteLength])
        padding = -offset % 4
        pieces.append(bytes(padding))
        view.byteOffset, view.byteLength = offset + padding, len(data)
        pieces.append(data)
        offset += padding + len(data)
    laid_out = b"".join(pieces) + bytes(-offset % 4)
    gltf.buffers[0].byteLength = len(laid_out)
    gltf.set_binary_blob(laid_out)


def _obj_text(textured: TexturedMesh) -> str:
    """Wavefront OBJ: one UV per vertex (the mesh is already split along UV seams)."""
    mesh = textured.mesh
    vertices = np.asarray(mesh.vertices)
    uv = np.asarray(mesh.visual.uv)
    faces = np.asarray(mesh.faces) + 1
    out = io.StringIO()
    out.write("# frontal3d textured model\nmtllib model.mtl\nusemtl frontal3d_texture\n")
    np.savetxt(out, vertices, fmt="v %.7g %.7g %.7g")
    np.savetxt(out, uv, fmt="vt %.7g %.7g")
    np.savetxt(out, np.repeat(faces, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
    return out.getvalue()


#: ``map_Bump`` carries the tangent-space normal map: Blender's OBJ importer reads
#: it as a normal map, which is what it is.
_MTL_TEXT = """# frontal3d material
newmtl frontal3d_texture
Ka 1.000 1.000 1.000
Kd 1.000 1.000 1.000
Ks 0.000 0.000 0.000
d 1.0
illum 1
map_Kd texture.png
map_Bump normal.png
"""


def debug_picture(array: np.ndarray) -> np.ndarray:
    """A viewable 8-bit picture of an intermediate map (mask, label map, depth)."""
    array = np.asarray(array)
    if array.ndim == 3 and array.dtype == np.uint8:
        return array
    if array.dtype == bool:
        return array.astype(np.uint8) * 255
    if np.issubdtype(array.dtype, np.integer):
        picture = _LABEL_PALETTE[np.mod(array, len(_LABEL_PALETTE))]
        picture[array < 0] = 0
        return picture
    values = np.asarray(array, dtype=np.float64)
    finite = np.isfinite(values)
    if not finite.any():
        return np.zeros(values.shape[:2], np.uint8)
    low, high = values[finite].min(), values[finite].max()
    scaled = (values - low) / (high - low if high > low else 1.0)
    return np.where(finite, np.clip(scaled * 254 + 1, 1, 255), 0).astype(np.uint8)


def _write_all(folder: Path, textured: TexturedMesh, landmarks: dict[str, np.ndarray], report: dict,
               debug_maps: dict[str, np.ndarray], preview_size: int | None) -> list[str]:
    # PIL encodes without holding the GIL: the two images take one encoding's time on two cores.
    # The material's own images are encoded: no third copy of a 13-megapixel atlas.
    material = textured.mesh.visual.material
    with ThreadPoolExecutor(max_workers=2) as pool:
        texture_png, normal_png = pool.map(_encode_png, (material.baseColorTexture, material.normalTexture))
    (folder / "model.glb").write_bytes(_glb_with_landmarks(textured, landmarks, texture_png, normal_png))
    (folder / "model.obj").write_text(_obj_text(textured))
    (folder / "model.mtl").write_text(_MTL_TEXT)
    (folder / "texture.png").write_bytes(texture_png)
    (folder / "normal.png").write_bytes(normal_png)
    names = ["model.glb", "model.obj", "model.mtl", "texture.png", "normal.png"]
    if preview_size:
        from frontal3d.preview import render_preview  # open3d loads only when a preview is wanted

        render_preview(textured, folder / "preview.png", size=preview_size)
        names.append("preview.png")
    if debug_maps:
        (folder / "debug").mkdir()
        for name, array in debug_maps.items():
            Image.fromarray(debug_picture(array)).save(folder / "debug" / f"{name}.png")
        names.append("debug")
    (folder / "report.json").write_text(json.dumps(report, indent=2, default=_json_default))
    names.append("report.json")
    return names


def check_output_folder(out_dir: Path) -> None:
    """Fail now, with the reason, if ``out_dir`` could not be written: before a long run, not after it.

    The folder may not exist yet; then its nearest existing parent must be a folder we may write into.
    """
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"output path {out_dir} exists and is not a folder")
    existing = next(parent for parent in (out_dir, *out_dir.parents) if parent.exists())
    if not existing.is_dir():
        raise InputError(f"cannot write into {out_dir}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"cannot write into {out_dir}: {existing} is not writable")


def export_all(out_dir: Path, textured: TexturedMesh, landmarks: dict[str, np.ndarray], report: dict,
               debug_maps: dict[str, np.ndarray] | None = None, preview_size: int | None = 512) -> dict[str, Path]:
    """Write the model files into ``out_dir`` and return ``{file name stem or kind: path}``.

    Keys: ``glb``, ``obj``, ``mtl``, ``texture``, ``normal``, ``report``, and
    ``preview`` (a 2 x 2 view sheet, unless ``preview_size`` is None) and ``debug``
    (a folder of intermediate maps as PNGs, when ``debug_maps`` is given). A new
    ``out_dir`` appears in one rename; into an existing one only these files are
    moved (each replaced atomically), so unrelated files there are never touched.
    """
    out_dir = Path(out_dir)
    for name, position in landmarks.items():
        if np.shape(position) != (3,) or not np.all(np.isfinite(position)):
            raise TemplateError(f"landmark {name!r} must be a finite 3D point, got {position!r}")
    check_output_folder(out_dir)
    try:
        out_dir.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", suffix=".partial", dir=out_dir.parent))
    except OSError as error:
        raise InputError(f"cannot write into {out_dir.parent}: {error.strerror or error}") from error
    try:
        staging.chmod(0o755)  # mkdtemp makes it private; the result is an ordinary folder
        names = _write_all(staging, textured, landmarks, report, debug_maps or {}, preview_size)
        if out_dir.exists():
            for name in names:
                target = out_dir / name
                if name == "debug" and target.exists():
                    shutil.rmtree(target)
                os.replace(staging / name, target)
            staging.rmdir()
        else:
            staging.rename(out_dir)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    keys = {"model.glb": "glb", "model.obj": "obj", "model.mtl": "mtl", "texture.png": "texture",
            "normal.png": "normal", "preview.png": "preview", "debug": "debug", "report.json": "report"}
    return {keys[name]: out_dir / name for name in names}
