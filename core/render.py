"""Orthographic front/back renders of a template, on one shared pixel grid.

Front and back share the grid, hence the silhouette: the paper's requirement for
warping both with the same deformation (section 3.2.1).
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import open3d as o3d
import trimesh

from frontal3d.errors import TemplateError
from frontal3d.family import Template


#: The per-pixel maps of a template render, in the order the cache stores them.
MAP_NAMES = ("mask", "front_depth", "back_depth", "front_normals", "back_normals", "front_regions", "back_regions")


@dataclass
class TemplateRenders:
    """Everything the image stages need from a template, as 2D maps.

    Grid convention (same as ../shared/data renders): square ``resolution`` x
    ``resolution``; pixel (row r, col c) has its centre at world
    ``(cx - hw + (c + 0.5) * 2hw / R,  cy + hw - (r + 0.5) * 2hw / R)``.
    Depths are world Z (the camera sits at +Z looking along -Z, so larger = nearer);
    NaN outside the mask. Normals are unit world vectors, 0 outside. Region maps hold
    the index into ``region_names``, -1 outside.
    """

    center: tuple[float, float]
    half_width: float
    mask: np.ndarray
    front_depth: np.ndarray
    back_depth: np.ndarray
    front_normals: np.ndarray
    back_normals: np.ndarray
    front_regions: np.ndarray
    back_regions: np.ndarray
    region_names: tuple[str, ...]
    landmarks: dict[str, np.ndarray] = field(default_factory=dict)

    def maps(self) -> dict[str, np.ndarray]:
        """The per-pixel maps by name (what the warp carries onto the image)."""
        return {name: getattr(self, name) for name in MAP_NAMES}

    @property
    def resolution(self) -> int:
        return int(self.mask.shape[0])

    @property
    def pixel_size(self) -> float:
        """World units per pixel."""
        return 2.0 * self.half_width / self.resolution

    def world_to_pixel(self, xy: np.ndarray) -> np.ndarray:
        """World (x, y) -> pixel (x=col, y=row) coordinates, pixel centres at integers."""
        xy = np.asarray(xy, dtype=np.float64)
        cx, cy = self.center
        col = (xy[..., 0] - (cx - self.half_width)) / self.pixel_size - 0.5
        row = ((cy + self.half_width) - xy[..., 1]) / self.pixel_size - 0.5
        return np.stack([col, row], axis=-1)

    def pixel_to_world(self, px: np.ndarray) -> np.ndarray:
        """Pixel (x=col, y=row) -> world (x, y); inverse of :meth:`world_to_pixel`."""
        px = np.asarray(px, dtype=np.float64)
        cx, cy = self.center
        x = cx - self.half_width + (px[..., 0] + 0.5) * self.pixel_size
        y = cy + self.half_width - (px[..., 1] + 0.5) * self.pixel_size
        return np.stack([x, y], axis=-1)


#: Bump when the render maps change meaning or layout: it invalidates every cache entry.
RENDER_VERSION = 1

#: Environment variable overriding the default render cache folder.
CACHE_DIR_ENV = "FRONTAL3D_CACHE_DIR"

_log = logging.getLogger("frontal3d.render")


@dataclass(frozen=True)
class OrthographicHits:
    """First hits of one orthographic ray per grid pixel, all arrays (R, R[, k]).

    ``facing`` is True where the hit triangle faces the ray's origin (what a
    rasterizer with back-face culling would draw).
    """

    hit: np.ndarray
    depth: np.ndarray
    normals: np.ndarray
    face_ids: np.ndarray
    facing: np.ndarray


def render_grid(mesh: trimesh.Trimesh, margin: float = 0.05) -> tuple[tuple[float, float], float]:
    """Centre and half width of the square grid framing ``mesh``'s XY bounding box.

    The longest XY extent spans ``1 - 2 * margin`` of the frame, so the silhouette
    never touches the border (contours and warps need a background ring).
    """
    if not 0.0 <= margin < 0.5:
        raise ValueError(f"margin must be in [0, 0.5), got {margin}")
    lo, hi = mesh.bounds[:, :2]
    center = (float((lo[0] + hi[0]) / 2), float((lo[1] + hi[1]) / 2))
    half_width = float(np.max(hi - lo)) / 2.0 / (1.0 - 2.0 * margin)
    return center, half_width


def raycast_front_back(
    mesh: trimesh.Trimesh,
    center: tuple[float, float],
    half_width: float,
    resolution: int,
) -> tuple[OrthographicHits, OrthographicHits]:
    """Cast one ray per pixel centre along -Z (front) and one along +Z (back).

    Both batches go through one BVH in one call. Depth is world Z of the first hit,
    NaN on a miss. Normals interpolate the vertex normals with the hit's barycentric
    coordinates and are flipped per hit to point toward the ray's origin side, so a
    mesh with reversed winding still renders outward normals.
    """
    if mesh.faces.shape[0] == 0:
        raise TemplateError("template mesh has no faces")
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.ascontiguousarray(mesh.vertices, dtype=np.float32)),
        o3d.core.Tensor(np.ascontiguousarray(mesh.faces, dtype=np.uint32)),
    )
    coords = (np.arange(resolution) + 0.5) * (2.0 * half_width / resolution)
    z_lo, z_hi = (float(z) for z in mesh.bounds[:, 2])
    pad = 0.01 * max(z_hi - z_lo, half_width) + 1e-6
    origin_z = np.array([z_hi + pad, z_lo - pad], dtype=np.float32)
    direction_z = np.array([-1.0, 1.0], dtype=np.float32)

    rays = np.zeros((2, resolution, resolution, 6), dtype=np.float32)
    rays[..., 0] = (center[0] - half_width + coords)[None, None, :]
    rays[..., 1] = (center[1] + half_width - coords)[None, :, None]
    rays[..., 2] = origin_z[:, None, None]
    rays[..., 5] = direction_z[:, None, None]
    result = {key: value.numpy() for key, value in scene.cast_rays(o3d.core.Tensor(rays)).items()}

    vertex_normals = np.asarray(mesh.vertex_normals, dtype=np.float32)
    faces = np.asarray(mesh.faces)
    sides = []
    for side in range(2):
        t_hit = result["t_hit"][side]
        hit = np.isfinite(t_hit)
        face_ids = np.full(hit.shape, -1, dtype=np.int64)
        depth = np.full(hit.shape, np.nan, dtype=np.float32)
        normals = np.zeros(hit.shape + (3,), dtype=np.float32)
        facing = np.zeros(hit.shape, dtype=bool)

        hit_faces = result["primitive_ids"][side][hit].astype(np.int64)
        uv = result["primitive_uvs"][side][hit]
        weights = np.stack([1.0 - uv[:, 0] - uv[:, 1], uv[:, 0], uv[:, 1]], axis=-1)
        smooth = np.einsum("nk,nkd->nd", weights, vertex_normals[faces[hit_faces]])
        hit_facing = result["primitive_normals"][side][hit][:, 2] * direction_z[side] < 0.0
        smooth *= np.where(hit_facing, 1.0, -1.0).astype(np.float32)[:, None]
        smooth /= np.maximum(np.linalg.norm(smooth, axis=-1, keepdims=True), 1e-12)

        face_ids[hit] = hit_faces
        depth[hit] = origin_z[side] + direction_z[side] * t_hit[hit]
        normals[hit] = smooth
        facing[hit] = hit_facing
        sides.append(OrthographicHits(hit=hit, depth=depth, normals=normals, face_ids=face_ids, facing=facing))
    return sides[0], sides[1]


def render_template(template: Template, resolution: int, margin: float = 0.05) -> TemplateRenders:
    """Front and back orthographic renders of ``template`` on one shared grid.

    The back render is the farthest surface along the same rays (cast from -Z), so
    both maps share one silhouette, as the paper's warping requires (section 3.2.1).
    """
    if resolution < 8:
        raise ValueError(f"resolution must be at least 8, got {resolution}")
    mesh = template.mesh
    face_regions = np.asarray(template.face_regions)
    if face_regions.shape != (len(mesh.faces),):
        raise TemplateError(
            f"template {template.family}/{template.subtype}: {face_regions.shape[0]} face regions for {len(mesh.faces)} faces"
        )
    center, half_width = render_grid(mesh, margin)
    front, back = raycast_front_back(mesh, center, half_width, resolution)
    mask = front.hit & back.hit

    def regions_of(hits: OrthographicHits) -> np.ndarray:
        return np.where(mask, face_regions[np.where(mask, hits.face_ids, 0)], -1).astype(np.int32)

    off = ~mask
    return TemplateRenders(
        center=center,
        half_width=half_width,
        mask=mask,
        front_depth=np.where(off, np.float32(np.nan), front.depth),
        back_depth=np.where(off, np.float32(np.nan), back.depth),
        front_normals=np.where(off[..., None], np.float32(0.0), front.normals),
        back_normals=np.where(off[..., None], np.float32(0.0), back.normals),
        front_regions=regions_of(front),
        back_regions=regions_of(back),
        region_names=tuple(template.region_names),
        landmarks={name: point.copy() for name, point in template.landmarks.items()},
    )


def front_back_mismatch(template: Template, resolution: int = 256, margin: float = 0.05) -> float:
    """Fraction of silhouette pixels where culled front and back renders disagree.

    A rasterizer with back-face culling sees a pixel from the front only if the
    first hit faces +Z, from the back only if it faces -Z. On a closed, consistently
    wound mesh both silhouettes are equal; holes or flipped patches make them differ.
    """
    center, half_width = render_grid(template.mesh, margin)
    front, back = raycast_front_back(template.mesh, center, half_width, resolution)
    union = front.hit | back.hit
    if not union.any():
        return 0.0
    return float(np.count_nonzero(front.facing != back.facing) / np.count_nonzero(union))


def default_cache_dir() -> Path:
    """``$FRONTAL3D_CACHE_DIR`` if set, else ``~/.cache/frontal3d/renders``."""
    configured = os.environ.get(CACHE_DIR_ENV)
    return Path(configured).expanduser() if configured else Path.home() / ".cache" / "frontal3d" / "renders"


def render_cache_key(template: Template, resolution: int, margin: float = 0.05) -> str:
    """sha256 over everything the renders depend on, so a stale entry is never reused."""
    digest = hashlib.sha256()
    digest.update(f"frontal3d-render-v{RENDER_VERSION}|{int(resolution)}|{float(margin)!r}|".encode())
    digest.update(np.ascontiguousarray(template.mesh.vertices, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(template.mesh.faces, dtype=np.int64).tobytes())
    digest.update(np.ascontiguousarray(template.face_regions, dtype=np.int32).tobytes())
    digest.update("\x1f".join(template.region_names).encode())
    for name in sorted(template.landmarks):
        digest.update(name.encode() + b"\x1f" + np.asarray(template.landmarks[name], dtype=np.float64).tobytes())
    return digest.hexdigest()


def cache_path_for(
    template: Template, resolution: int, margin: float = 0.05, cache_dir: Path | None = None
) -> Path:
    """Where :func:`load_or_render` keeps the renders of this template and grid."""
    return _entry_path(template, resolution, render_cache_key(template, resolution, margin), cache_dir)


def _entry_path(template: Template, resolution: int, key: str, cache_dir: Path | None) -> Path:
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return folder / f"{template.family}-{template.subtype}-{resolution}-{key[:24]}.npz"


def load_or_render(
    template: Template, resolution: int, cache_dir: Path | None = None, margin: float = 0.05
) -> TemplateRenders:
    """Renders from the disk cache, or rendered and stored there.

    A corrupt or truncated entry is logged as a warning and rebuilt; a cache folder
    that cannot be written is logged and skipped (the renders are still returned).
    """
    key = render_cache_key(template, resolution, margin)
    path = _entry_path(template, resolution, key, cache_dir)
    if path.exists():
        try:
            return _read_renders(path, key, resolution)
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as error:
            _log.warning("render cache entry %s is unusable (%s); re-rendering", path, error)
    renders = render_template(template, resolution, margin)
    try:
        _write_renders(path, key, renders)
    except OSError as error:
        _log.warning("cannot write render cache entry %s (%s); continuing without cache", path, error)
    return renders


def _write_renders(path: Path, key: str, renders: TemplateRenders) -> None:
    """Write to a temporary file in the same folder, then rename: readers never see half a file.

    Uncompressed: loading is about 3x faster than from a compressed archive, which is
    the point of the cache; an entry is ~10 MB at 512^2.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    names = sorted(renders.landmarks)
    arrays = {
        "key": np.array(key),
        "center": np.asarray(renders.center, dtype=np.float64),
        "half_width": np.array(renders.half_width, dtype=np.float64),
        **renders.maps(),
        "region_names": np.array(renders.region_names, dtype=str),
        "landmark_names": np.array(names, dtype=str),
        "landmark_points": np.array([renders.landmarks[n] for n in names], dtype=np.float64).reshape(-1, 3),
    }
    handle, temp_name = tempfile.mkstemp(dir=path.parent, prefix=path.stem, suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as stream:
            np.savez(stream, **arrays)
        os.replace(temp_name, path)
    except BaseException:
        Path(temp_name).unlink(missing_ok=True)
        raise


def _read_renders(path: Path, key: str, resolution: int) -> TemplateRenders:
    """Load one cache entry, raising ValueError/KeyError on anything inconsistent."""
    with np.load(path, allow_pickle=False) as data:
        arrays = {name: data[name] for name in data.files}
    if str(arrays["key"]) != key:
        raise ValueError("key does not match the template")
    grid = (resolution, resolution)
    expected = {
        "center": (2,),
        "half_width": (),
        "mask": grid,
        "front_depth": grid,
        "back_depth": grid,
        "front_normals": grid + (3,),
        "back_normals": grid + (3,),
        "front_regions": grid,
        "back_regions": grid,
        "landmark_points": (len(arrays["landmark_names"]), 3),
    }
    wrong = [name for name, shape in expected.items() if arrays[name].shape != shape]
    if wrong:
        raise ValueError(f"wrong shape for {', '.join(wrong)}")
    names = [str(n) for n in arrays["landmark_names"]]
    return TemplateRenders(
        center=(float(arrays["center"][0]), float(arrays["center"][1])),
        half_width=float(arrays["half_width"]),
        mask=arrays["mask"].astype(bool),
        front_depth=arrays["front_depth"],
        back_depth=arrays["back_depth"],
        front_normals=arrays["front_normals"],
        back_normals=arrays["back_normals"],
        front_regions=arrays["front_regions"],
        back_regions=arrays["back_regions"],
        region_names=tuple(str(n) for n in arrays["region_names"]),
        landmarks={n: p.copy() for n, p in zip(names, arrays["landmark_points"])},
    )
