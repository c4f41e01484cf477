"""Texture (paper 3.2.6): project the photo onto the front, invent the back, add relief.

The atlas is one image at the photo's full resolution: the front texture (the photo,
occlusions inpainted per region) on the left and the back texture (a family rule) on
the right, both cropped to the object's bounding box plus a margin so no detail is
lost and no background pixels are wasted. Side faces reuse the UVs of their front
boundary pixels at both ends, stretching those pixels around the rim as the paper
does; that needs a second copy of the rim vertices with their own UVs, so the
textured mesh is no longer watertight and a closed copy is kept beside it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
import trimesh
from PIL import Image
from scipy import ndimage

from frontal3d.back_rules import BUILTIN_BACK_RULES, BackRule
from frontal3d.errors import ConfigError, InputError
from frontal3d.stages.inpaint import inpaint_regions

if TYPE_CHECKING:
    from frontal3d.stages.mesh import MeshResult

#: Margin around the object's bounding box kept in the atlas, as a share of its
#: larger side: room for bilinear filtering and mipmaps at the silhouette.
ATLAS_MARGIN = 0.02


@dataclass
class TexturedMesh:
    """The textured model: ``mesh`` carries UVs and a PBR material (rim vertices split
    per UV), ``watertight_mesh`` the same closed geometry without the split.
    ``atlas`` (h, 2w, 3 uint8) = front half | back half; ``normal_map`` is its
    tangent-space normal map (RGB = (n + 1) / 2, +X right, +Y up, as glTF expects).
    ``front_synthesized`` (h, w bool) marks the front half's texels that are not the photo's
    own pixel there: inpainted under occluders, or bled beyond the silhouette;
    ``front_shown`` (h, w bool) the front half's texels inside the silhouette, the ones the
    model shows (the rest only pad the rim for filtering).
    """

    mesh: trimesh.Trimesh
    atlas: np.ndarray
    normal_map: np.ndarray
    watertight_mesh: trimesh.Trimesh
    front_synthesized: np.ndarray
    front_shown: np.ndarray


def _bleed(texture: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Copy each outside pixel's nearest inside colour, so filtering at the rim never sees background."""
    if inside.all() or not inside.any():
        return texture
    nearest = ndimage.distance_transform_edt(~inside, return_distances=False, return_indices=True)
    return texture[nearest[0], nearest[1]]


def normal_map_from_texture(texture: np.ndarray, strength: float) -> np.ndarray:
    """Tangent-space normal map treating grey level as height (paper: bump from derivatives).

    Height h = grey in [0, 1] times ``strength`` per pixel; n = normalize(-dh/dx, -dh/dy_up, 1).
    """
    grey = cv2.cvtColor(texture, cv2.COLOR_RGB2GRAY).astype(np.float32) / 255.0
    d_col = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8, borderType=cv2.BORDER_REPLICATE)
    d_row = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3, scale=1 / 8, borderType=cv2.BORDER_REPLICATE)
    # Per channel, in place: a stacked (h, w, 3) array and np.linalg.norm took 3.7 s per 34-megapixel half.
    d_col *= -strength
    d_row *= strength
    length = cv2.sqrt(d_col * d_col + d_row * d_row + 1.0)
    channels = [cv2.convertScaleAbs(np.rint((c / length + 1.0) * 127.5)) for c in (d_col, d_row, np.ones_like(grey))]
    return cv2.merge(channels)


def _resolve_rule(back_rule: BackRule | str) -> BackRule:
    if callable(back_rule):
        return back_rule
    if back_rule not in BUILTIN_BACK_RULES:
        raise ConfigError(f"unknown back rule {back_rule!r}; built-in rules are {sorted(BUILTIN_BACK_RULES)}")
    return BUILTIN_BACK_RULES[back_rule]


def _check_inputs(mesh_result: MeshResult, image: np.ndarray, mask: np.ndarray, region_map: np.ndarray,
                  occlusion_mask: np.ndarray, working_to_full: float) -> None:
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise InputError(f"texture: image must be H x W x 3 uint8, got {image.shape} {image.dtype}")
    for name, array in (("mask", mask), ("region map", region_map), ("occlusion mask", occlusion_mask)):
        if array.shape != image.shape[:2]:
            raise InputError(f"texture: {name} {array.shape} does not match the image {image.shape[:2]}")
    if not mask.any():
        raise InputError("texture: the object mask is empty")
    if not working_to_full > 0:
        raise InputError(f"texture: working_to_full must be positive, got {working_to_full}")
    n_vertices = len(mesh_result.mesh.vertices)
    if mesh_result.vertex_pixel.shape != (n_vertices, 2) or mesh_result.vertex_side.shape != (n_vertices,):
        raise InputError("texture: vertex_pixel / vertex_side do not match the mesh's vertex count")


def build_textured_mesh(mesh_result: MeshResult, image: np.ndarray, mask: np.ndarray, region_map: np.ndarray,
                        occlusion_mask: np.ndarray, region_names: tuple[str, ...], back_rule: BackRule | str,
                        back_params: dict[str, Any] | None, working_to_full: float,
                        bump_strength: float = 1.0) -> TexturedMesh:
    """Texture ``mesh_result`` from the full-resolution photo.

    ``back_rule`` is a rule function or the name of one in
    :data:`frontal3d.back_rules.BUILTIN_BACK_RULES`; ``working_to_full`` maps the
    mesh's working-resolution ``vertex_pixel`` to full-resolution pixels.
    """
    image = np.asarray(image)
    mask = np.asarray(mask, dtype=bool)
    region_map = np.asarray(region_map)
    occlusion_mask = np.asarray(occlusion_mask, dtype=bool)
    _check_inputs(mesh_result, image, mask, region_map, occlusion_mask, working_to_full)
    height, width = mask.shape

    fill = occlusion_mask & mask
    front = inpaint_regions(image, region_map, fill) if fill.any() else image
    back = np.asarray(_resolve_rule(back_rule)(front, mask, region_map, tuple(region_names), dict(back_params or {})))
    if back.shape != image.shape:
        raise ConfigError(f"back rule returned shape {back.shape}, expected the image's {image.shape}")
    back = back.astype(np.uint8)

    # Full-resolution position of each vertex: working pixel centres map to the
    # centres of the full-resolution blocks they cover.
    full_px = (np.asarray(mesh_result.vertex_pixel, dtype=np.float64) + 0.5) * working_to_full - 0.5
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    margin = max(4, int(np.ceil(ATLAS_MARGIN * max(rows[-1] - rows[0], cols[-1] - cols[0]))))
    y0 = int(max(0, min(rows[0], np.floor(full_px[:, 1].min())) - margin))
    y1 = int(min(height, max(rows[-1] + 1, np.ceil(full_px[:, 1].max()) + 1) + margin))
    x0 = int(max(0, min(cols[0], np.floor(full_px[:, 0].min())) - margin))
    x1 = int(min(width, max(cols[-1] + 1, np.ceil(full_px[:, 0].max()) + 1) + margin))
    crop_h, crop_w = y1 - y0, x1 - x0

    front_half = _bleed(front[y0:y1, x0:x1], mask[y0:y1, x0:x1])
    back_window = slice(width - x1, width - x0)
    back_half = _bleed(back[y0:y1, back_window], np.fliplr(mask)[y0:y1, back_window])
    atlas = np.ascontiguousarray(np.concatenate([front_half, back_half], axis=1))
    normal_map = np.concatenate([normal_map_from_texture(front_half, bump_strength),
                                 normal_map_from_texture(back_half, bump_strength)], axis=1)

    # UVs follow trimesh's convention (v = 0 at the image's bottom row).
    v = 1.0 - (full_px[:, 1] - y0 + 0.5) / crop_h
    front_u = (full_px[:, 0] - x0 + 0.5) / (2 * crop_w)
    back_u = (crop_w + (x1 - 1 - full_px[:, 0]) + 0.5) / (2 * crop_w)
    is_back = np.asarray(mesh_result.vertex_side) == 1
    uv = np.clip(np.stack([np.where(is_back, back_u, front_u), v], axis=1), 0.0, 1.0)
    rim_uv = np.clip(np.stack([front_u, v], axis=1), 0.0, 1.0)

    watertight = mesh_result.mesh
    faces = np.asarray(watertight.faces)
    face_sides = is_back[faces]
    side = face_sides.any(axis=1) & ~face_sides.all(axis=1)
    rim_vertices, rim_faces = np.unique(faces[side], return_inverse=True)
    split_faces = faces.copy()
    split_faces[side] = len(watertight.vertices) + rim_faces.reshape(-1, 3)
    vertices = np.concatenate([watertight.vertices, watertight.vertices[rim_vertices]])
    material = trimesh.visual.material.PBRMaterial(
        name="frontal3d_texture",
        baseColorTexture=Image.fromarray(atlas),
        normalTexture=Image.fromarray(normal_map),
        metallicFactor=0.0,
        roughnessFactor=1.0,
    )
    visual = trimesh.visual.TextureVisuals(uv=np.concatenate([uv, rim_uv[rim_vertices]]), material=material)
    textured = trimesh.Trimesh(vertices=vertices, faces=split_faces, visual=visual, process=False)
    front_shown = mask[y0:y1, x0:x1]
    return TexturedMesh(mesh=textured, atlas=atlas, normal_map=normal_map, watertight_mesh=watertight.copy(),
                        front_synthesized=fill[y0:y1, x0:x1] | ~front_shown, front_shown=front_shown)
