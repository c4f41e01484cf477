"""Pictures a user looks at instead of reading numbers.

- A textured model's preview, four orthographic views in one PNG: a user (or a test)
  can check the texture landed where it should without a 3D viewer. Rays are cast
  with open3d's RaycastingScene, each hit's barycentric coordinates interpolate the
  triangle's UVs, the atlas is sampled bilinearly and shaded with a simple Lambert
  term so the relief of the geometry stays readable.
- The outline a turned-down photo was judged by (:func:`outline_sheet`): most wrong
  verdicts come from a wrong outline (a kerb taken in, a wing lost), which one look shows.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import open3d as o3d
from PIL import Image

from frontal3d.stages.texture import TexturedMesh

BACKGROUND = np.array([235, 235, 235], np.uint8)

#: Direction from the object towards the camera for each preview view (canonical frame).
PREVIEW_VIEWS: dict[str, np.ndarray] = {
    "front": np.array([0.0, 0.0, 1.0]),
    "back": np.array([0.0, 0.0, -1.0]),
    "side": np.array([1.0, 0.0, 0.0]),
    "three-quarter": np.array([np.sin(np.radians(40)), np.sin(np.radians(20)), np.cos(np.radians(40))]),
}


def _camera_axes(towards_camera: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Forward, right and up unit vectors of a camera looking back along ``towards_camera``."""
    forward = -np.asarray(towards_camera, dtype=np.float64)
    forward /= np.linalg.norm(forward)
    up_hint = np.array([0.0, 1.0, 0.0]) if abs(forward[1]) < 0.99 else np.array([0.0, 0.0, -1.0])
    right = np.cross(forward, up_hint)
    right /= np.linalg.norm(right)
    return forward, right, np.cross(right, forward)


def render_view(textured: TexturedMesh, towards_camera: np.ndarray, width: int, height: int,
                center: np.ndarray, half_extent: tuple[float, float], shade: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Orthographic render of the textured mesh; returns (RGB uint8 image, hit mask).

    The image plane is centred on ``center`` (3D) and spans ``2 * half_extent``
    (horizontal, vertical) world units; pixel centres sit at the usual half-pixel
    offsets, so the front view can be laid exactly over the photo's pixel grid.
    ``shade=False`` returns the bare texture colour (for checking reprojection).
    """
    mesh = textured.mesh
    center = np.asarray(center, dtype=np.float64)
    forward, right, up = _camera_axes(towards_camera)
    radius = float(np.linalg.norm(mesh.bounds[1] - mesh.bounds[0])) + 1.0
    cols = ((np.arange(width) + 0.5) / width * 2.0 - 1.0) * half_extent[0]
    rows = (1.0 - (np.arange(height) + 0.5) / height * 2.0) * half_extent[1]
    origins = (center - forward * (radius + np.linalg.norm(center - mesh.centroid))
               + cols[None, :, None] * right + rows[:, None, None] * up)
    rays = np.concatenate([origins.reshape(-1, 3), np.broadcast_to(forward, (width * height, 3))], axis=1)

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
                        o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)))
    hits = scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))
    triangle = hits["primitive_ids"].numpy().astype(np.int64)
    hit = triangle != o3d.t.geometry.RaycastingScene.INVALID_ID
    bary = hits["primitive_uvs"].numpy().astype(np.float64)[hit]
    corner_uv = np.asarray(mesh.visual.uv, np.float64)[np.asarray(mesh.faces)[triangle[hit]]]
    uv = ((1.0 - bary.sum(axis=1))[:, None] * corner_uv[:, 0] + bary[:, [0]] * corner_uv[:, 1]
          + bary[:, [1]] * corner_uv[:, 2])

    atlas = textured.atlas
    atlas_h, atlas_w = atlas.shape[:2]
    map_x = np.zeros(width * height, np.float32)
    map_y = np.zeros(width * height, np.float32)
    map_x[hit] = uv[:, 0] * atlas_w - 0.5
    map_y[hit] = (1.0 - uv[:, 1]) * atlas_h - 0.5
    colour = cv2.remap(atlas, map_x.reshape(height, width), map_y.reshape(height, width), cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_REPLICATE).reshape(-1, 3)[hit].astype(np.float64)
    if shade:
        light = -forward + 0.4 * up - 0.3 * right
        light /= np.linalg.norm(light)
        normals = hits["primitive_normals"].numpy().astype(np.float64)[hit]
        colour *= (0.35 + 0.65 * np.abs(normals @ light))[:, None]
    image = np.tile(BACKGROUND, (width * height, 1))
    image[hit] = np.clip(np.rint(colour), 0, 255).astype(np.uint8)
    return image.reshape(height, width, 3), hit.reshape(height, width)


def render_preview(textured: TexturedMesh, out_png: Path, size: int = 512) -> np.ndarray:
    """Write front, back, side and three-quarter views (2 x 2, labelled) to ``out_png``.

    Each view is ``size`` pixels square and uses the same scale, so the views can be
    compared with each other. Returns the composed RGB image.
    """
    bounds = textured.mesh.bounds
    center = bounds.mean(axis=0)
    half = 0.55 * float(np.linalg.norm(bounds[1] - bounds[0]))
    tiles = []
    for name, direction in PREVIEW_VIEWS.items():
        tile, _ = render_view(textured, direction, size, size, center, (half, half))
        cv2.putText(tile, name, (10, 28), cv2.FONT_HERSHEY_SIMPLEX, 0.8, (20, 20, 20), 2, cv2.LINE_AA)
        tiles.append(tile)
    sheet = np.concatenate([np.concatenate(tiles[:2], axis=1), np.concatenate(tiles[2:], axis=1)], axis=0)
    Image.fromarray(sheet).save(out_png)
    return sheet


#: Long side, in pixels, of each panel of :func:`outline_sheet`.
OUTLINE_PANEL = 640
#: Outline colour (RGB) and how bright the photo stays outside the outline.
OUTLINE_COLOUR = (255, 0, 200)
OUTSIDE_BRIGHTNESS = 0.35


def outline_sheet(rgb: np.ndarray, outlines: dict[str, np.ndarray]) -> np.ndarray:
    """RGB sheet, one panel per family: the photo dimmed outside the outline judged, the
    outline drawn over it and labelled with the family."""
    scale = min(1.0, OUTLINE_PANEL / max(rgb.shape[:2]))
    size = (max(1, round(rgb.shape[1] * scale)), max(1, round(rgb.shape[0] * scale)))
    photo = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
    panels = []
    for family, mask in outlines.items():
        inside = cv2.resize(mask.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
        panel = np.where(inside[..., None], photo, (photo * OUTSIDE_BRIGHTNESS).astype(np.uint8))
        contours, _ = cv2.findContours(inside.astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(panel, contours, -1, OUTLINE_COLOUR, 2, cv2.LINE_AA)
        cv2.putText(panel, f"{family}: outline judged", (10, 28), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 255), 2, cv2.LINE_AA)
        panels.append(panel)
    return np.concatenate(panels, axis=1)
