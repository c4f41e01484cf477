"""Frontal "photos" of coloured meshes: the inputs of evaluation, examples and synthetic data.

Orthographic along -Z (the canonical view), one ray per pixel centre, Lambert shading
with flat normals turned toward the camera, the same camera convention as the shared
renders (``center``, ``half_width``, ``resolution``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import open3d as o3d
import trimesh

#: Light directions (toward the light) and weights: ambient + camera + upper-left-front.
_AMBIENT = 0.15
_LIGHTS = ((np.array([0.0, 0.0, 1.0]), 0.65), (np.array([-0.5, 0.6, 0.62]) / np.linalg.norm([-0.5, 0.6, 0.62]), 0.25))


def load_coloured_mesh(path: Path) -> trimesh.Trimesh:
    """One mesh with per-face colours from a GLB/OBJ's materials, textures or vertex colours."""
    scene = trimesh.load(str(path), force="scene")
    parts = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        geometry = scene.geometry[name]
        if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
            continue
        part = geometry.copy()
        part.apply_transform(transform)
        colours = _face_colours(part)
        part.visual = trimesh.visual.ColorVisuals(part, face_colors=colours)
        parts.append(part)
    if not parts:
        raise ValueError(f"{path}: no triangles")
    return trimesh.util.concatenate(parts)


def _face_colours(mesh: trimesh.Trimesh) -> np.ndarray:
    material = getattr(mesh.visual, "material", None)
    if material is not None and getattr(material, "image", None) is None and getattr(material, "baseColorTexture", None) is None:
        colour = np.asarray(material.main_color, dtype=np.uint8)
        return np.tile(colour, (len(mesh.faces), 1))
    try:
        colour_visuals = mesh.visual.to_color()
        colours = np.asarray(colour_visuals.face_colors, dtype=np.uint8)
        if colours.shape[0] == len(mesh.faces):
            return colours
    except (AttributeError, ValueError, IndexError):
        pass
    return np.tile(np.array([200, 200, 200, 255], np.uint8), (len(mesh.faces), 1))


def frontal_camera(mesh: trimesh.Trimesh, resolution: int = 512, fill: float = 0.9) -> dict[str, Any]:
    """A square view centred on the XY bounding box; the longest XY extent spans ``fill``."""
    lo, hi = mesh.bounds[0, :2], mesh.bounds[1, :2]
    centre = (lo + hi) / 2
    half_width = float(np.max(hi - lo)) / 2 / fill
    return {"center": [float(centre[0]), float(centre[1])], "half_width": half_width, "resolution": [resolution, resolution]}


def render_frontal(mesh: trimesh.Trimesh, camera: dict[str, Any]) -> np.ndarray:
    """RGBA uint8 image of ``mesh`` (per-face colours) seen along -Z; alpha = silhouette."""
    width, height = camera["resolution"]
    cx, cy = camera["center"]
    hw = camera["half_width"]
    xs = cx - hw + (np.arange(width) + 0.5) * 2 * hw / width
    ys = cy + hw - (np.arange(height) + 0.5) * 2 * hw / height
    gx, gy = np.meshgrid(xs, ys)
    z0 = float(mesh.bounds[1, 2]) + 1.0
    rays = np.zeros((height, width, 6), np.float32)
    rays[..., 0], rays[..., 1], rays[..., 2], rays[..., 5] = gx, gy, z0, -1.0
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)), o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)))
    hits = scene.cast_rays(o3d.core.Tensor(rays))
    face = hits["primitive_ids"].numpy().astype(np.int64)
    inside = np.isfinite(hits["t_hit"].numpy())
    normals = np.asarray(mesh.face_normals)[np.where(inside, face, 0)]
    normals = np.where(normals[..., 2:3] < 0, -normals, normals)
    shade = _AMBIENT + sum(w * np.clip(normals @ d, 0, 1) for d, w in _LIGHTS)
    colours = np.asarray(mesh.visual.face_colors)[np.where(inside, face, 0), :3].astype(np.float64)
    rgb = np.clip(colours * shade[..., None], 0, 255).astype(np.uint8)
    rgba = np.zeros((height, width, 4), np.uint8)
    rgba[..., :3] = np.where(inside[..., None], rgb, 0)
    rgba[..., 3] = inside * 255
    return rgba


def composite(rgba: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Put an RGBA render over an RGB background of the same size."""
    alpha = rgba[..., 3:4].astype(np.float32) / 255.0
    return (rgba[..., :3] * alpha + background * (1 - alpha)).astype(np.uint8)
