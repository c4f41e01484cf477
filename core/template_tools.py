"""Turn a user's mesh into a checked family template, and draw a template's contact sheet.

A template feeds every image stage through its renders, so a bad one (open, lying on
the wrong axis, unlabelled) would quietly ruin each reconstruction: here every problem
is either repaired with a warning or refused with a :class:`TemplateError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import manifold3d
import numpy as np
import open3d as o3d
import trimesh
from scipy.spatial import cKDTree
from skimage import measure

from frontal3d.errors import TemplateError, UnknownFamilyError
from frontal3d.family import Family, Template
from frontal3d.render import TemplateRenders, front_back_mismatch, raycast_front_back, render_grid

SUPPORTED_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".stl")

#: Largest tolerated fraction of silhouette pixels where culled front and back renders differ.
MAX_SILHOUETTE_MISMATCH = 0.01

#: An axis counts as thinner/longer than another only beyond this ratio (a cube has no wrong way).
_AXIS_TOLERANCE = 1.05

#: Voxels along the longest edge when an open mesh must be remeshed to close it.
_REPAIR_VOXELS = 128

_AXES = "XYZ"


@dataclass(frozen=True)
class _LabelSource:
    """One way of grouping the faces: a name per face (geometry, material or colour)."""

    kind: str
    face_names: np.ndarray


def template_from_mesh(
    path: Path, family: Family, subtype: str, regions: dict[str, str] | None = None
) -> tuple[Template, list[str]]:
    """Load a GLB/glTF/OBJ/PLY/STL mesh as ``family``'s template for ``subtype``.

    Region labels come from the mesh's face groups, tried in order: scene geometry
    names, material names, vertex (or face) colours written ``#rrggbb``. A group
    name must equal a region name (any case) or be a key of ``regions``. Returns the
    template and the warnings about what was repaired or is doubtful.
    """
    path = Path(path)
    if subtype not in family.subtypes:
        raise UnknownFamilyError(f"family {family.name!r} has no subtype {subtype!r} (has {', '.join(family.subtypes)})")
    region_names = tuple(family.regions[subtype])
    if regions:
        bad_targets = sorted({r for r in regions.values() if r not in region_names})
        if bad_targets:
            raise TemplateError(
                f"regions maps to {bad_targets}, not {family.name}/{subtype} regions {list(region_names)}"
            )
    warnings: list[str] = []
    vertices, faces, sources = _load_labelled_faces(path)
    face_regions = _label_faces(sources, region_names, regions, path, warnings)

    mesh, face_regions = _clean(trimesh.Trimesh(vertices, faces, process=False), face_regions)
    _check_orientation(mesh, family, path)
    mesh, face_regions = _make_watertight(mesh, face_regions, path, warnings)

    empty = [name for i, name in enumerate(region_names) if not np.any(face_regions == i)]
    if empty:
        warnings.append(f"{path.name}: no faces labelled {empty}; region-guided steps will ignore them")
    template = Template(family.name, subtype, mesh, face_regions, region_names)
    mismatch = front_back_mismatch(template)
    if mismatch > MAX_SILHOUETTE_MISMATCH:
        warnings.append(
            f"{path.name}: front and back silhouettes differ on {mismatch:.1%} of pixels "
            "(faces seen from inside or double-sided sheets); check the mesh's normals"
        )
    return template, warnings


def _load_labelled_faces(path: Path) -> tuple[np.ndarray, np.ndarray, list[_LabelSource]]:
    """All scene geometry in world coordinates, plus every available face grouping."""
    if path.suffix.lower() not in SUPPORTED_SUFFIXES:
        raise TemplateError(f"{path.name}: unsupported mesh format (use one of {', '.join(SUPPORTED_SUFFIXES)})")
    if not path.is_file():
        raise TemplateError(f"template mesh not found: {path}")
    try:
        scene = trimesh.load_scene(path)
    except Exception as error:  # trimesh raises many types for malformed files
        raise TemplateError(f"cannot read template mesh {path.name}: {error}") from error

    vertices, faces, geometry_names, material_names, colour_names = [], [], [], [], []
    offset = 0
    for node in scene.graph.nodes_geometry:
        transform, geometry_name = scene.graph[node]
        geometry = scene.geometry[geometry_name]
        if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
            continue
        count = len(geometry.faces)
        vertices.append(trimesh.transform_points(geometry.vertices, transform))
        faces.append(np.asarray(geometry.faces, dtype=np.int64) + offset)
        offset += len(geometry.vertices)
        geometry_names.append(np.full(count, geometry_name, dtype=object))
        material = getattr(getattr(geometry.visual, "material", None), "name", None)
        material_names.append(np.full(count, material, dtype=object) if material else None)
        colour_names.append(_face_colour_names(geometry))
    if not faces:
        raise TemplateError(f"{path.name} holds no triangles")

    sources = [_LabelSource("geometry", np.concatenate(geometry_names))]
    for kind, parts in (("material", material_names), ("colour", colour_names)):
        if all(part is not None for part in parts):
            sources.append(_LabelSource(kind, np.concatenate(parts)))
    return np.concatenate(vertices), np.concatenate(faces), sources


def _face_colour_names(geometry: trimesh.Trimesh) -> np.ndarray | None:
    """``#rrggbb`` per face from face colours, or the majority of its vertices' colours."""
    kind = geometry.visual.kind
    if kind == "face":
        rgb = np.asarray(geometry.visual.face_colors)[:, :3].astype(np.int64)
    elif kind == "vertex":
        corners = np.asarray(geometry.visual.vertex_colors)[geometry.faces][:, :, :3].astype(np.int64)
        second_wins = np.all(corners[:, 1] == corners[:, 2], axis=1)
        rgb = np.where(second_wins[:, None], corners[:, 1], corners[:, 0])
    else:
        return None
    packed = (rgb[:, 0] << 16) | (rgb[:, 1] << 8) | rgb[:, 2]
    return np.char.mod("#%06x", packed).astype(object)


def _label_faces(
    sources: list[_LabelSource],
    region_names: tuple[str, ...],
    regions: dict[str, str] | None,
    path: Path,
    warnings: list[str],
) -> np.ndarray:
    """Region index per face from the first grouping whose names all resolve.

    A grouping with several groups wins over a single group; if groups exist but no
    grouping resolves, the error lists the unknown names of the first one.
    """
    by_lower = {name.lower(): i for i, name in enumerate(region_names)}

    def resolve(name: str) -> int | None:
        if regions and name in regions:
            return region_names.index(regions[name])
        return by_lower.get(str(name).strip().lower())

    groupings = [(source, np.unique(source.face_names.astype(str))) for source in sources]
    resolvable = [(s, names) for s, names in groupings if all(resolve(n) is not None for n in names)]
    grouped = [(s, names) for s, names in groupings if len(names) > 1]
    chosen = next(((s, n) for s, n in resolvable if len(n) > 1), None)
    if chosen is None and not grouped and resolvable:
        chosen = resolvable[0]
    if chosen is None and not grouped and not regions:
        warnings.append(
            f"{path.name}: no face groups (geometry names, materials or vertex colours) name a region; "
            f"every face labelled {region_names[0]!r}"
        )
        return np.zeros(len(sources[0].face_names), dtype=np.int32)
    if chosen is None:
        source, names = grouped[0] if grouped else groupings[0]
        unknown = [n for n in names if resolve(n) is None]
        raise TemplateError(
            f"{path.name}: {source.kind} names {unknown} are not regions {list(region_names)}; "
            "rename them or map them with regions={name: region}"
        )
    source, names = chosen
    lookup = np.array([resolve(n) for n in names], dtype=np.int32)
    return lookup[np.searchsorted(names, source.face_names.astype(str))]


def _clean(mesh: trimesh.Trimesh, face_regions: np.ndarray) -> tuple[trimesh.Trimesh, np.ndarray]:
    """Weld vertices split at UV/normal seams; drop degenerate and duplicate faces."""
    mesh.merge_vertices()
    keep = mesh.nondegenerate_faces() & mesh.unique_faces()
    mesh.update_faces(keep)
    mesh.remove_unreferenced_vertices()
    return mesh, face_regions[keep]


def _check_orientation(mesh: trimesh.Trimesh, family: Family, path: Path) -> None:
    """Refuse a mesh whose axes cannot match the family's canonical view (camera along -Z)."""
    extents = mesh.extents
    sizes = ", ".join(f"{axis}={size:.3g}" for axis, size in zip(_AXES, extents))
    if family.canonical_view in ("front", "top"):
        thinnest = int(np.argmin(extents))
        if thinnest != 2 and extents[2] > _AXIS_TOLERANCE * extents[thinnest]:
            turn_about = "X" if thinnest == 1 else "Y"
            raise TemplateError(
                f"{path.name}: Z is not the thinnest axis ({sizes}) but the {family.name} "
                f"'{family.canonical_view}' view looks along -Z; rotate the mesh 90 deg about {turn_about} "
                f"to bring its thinnest axis {_AXES[thinnest]} onto Z"
            )
    elif family.canonical_view == "side":
        if extents[2] > _AXIS_TOLERANCE * max(extents[0], extents[1]):
            raise TemplateError(
                f"{path.name}: Z is the longest axis ({sizes}) but the {family.name} 'side' view "
                "shows the length across the image; rotate the mesh 90 deg about Y to lay it along X"
            )


def _make_watertight(
    mesh: trimesh.Trimesh, face_regions: np.ndarray, path: Path, warnings: list[str]
) -> tuple[trimesh.Trimesh, np.ndarray]:
    """Close holes (fans over each boundary loop, else a voxel remesh), orient outward.

    manifold3d has the last word: a mesh it does not accept as a manifold is refused.
    """
    if not mesh.is_watertight:
        filled, holes = _fill_boundary_loops(mesh)
        if filled.is_watertight:
            warnings.append(f"{path.name}: mesh was not watertight; filled {holes} hole(s)")
            face_regions = _transfer_labels(mesh, face_regions, filled, kept=len(mesh.faces))
            mesh = filled
        else:
            remeshed = _voxel_remesh(mesh, path)
            face_regions = _transfer_labels(mesh, face_regions, remeshed, kept=0)
            mesh = remeshed
            warnings.append(
                f"{path.name}: mesh was not watertight and its holes are not simple loops; "
                f"remeshed from {_REPAIR_VOXELS} voxels along its longest edge (fine detail is lost)"
            )
    if not mesh.is_winding_consistent:
        trimesh.repair.fix_winding(mesh)
        warnings.append(f"{path.name}: face winding was inconsistent; re-oriented the faces")
    if mesh.volume < 0:
        mesh.invert()
        warnings.append(f"{path.name}: faces pointed inward; flipped them to face outward")
    as_manifold = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.ascontiguousarray(mesh.vertices, dtype=np.float32),
            tri_verts=np.ascontiguousarray(mesh.faces, dtype=np.uint32),
        )
    )
    if as_manifold.status() != manifold3d.Error.NoError or mesh.volume <= 0:
        raise TemplateError(f"{path.name}: cannot be repaired into a closed manifold ({as_manifold.status().name})")
    return mesh, face_regions


def _fill_boundary_loops(mesh: trimesh.Trimesh) -> tuple[trimesh.Trimesh, int]:
    """Close every boundary loop with a fan around a new vertex at its centroid.

    Each fan runs against its loop's existing faces, so the winding stays consistent;
    original faces keep their order (new ones are appended), so labels stay valid.
    """
    loops = [entity.points[:-1] for entity in mesh.outline().entities if entity.closed and len(entity.points) > 3]
    directed_edges = np.asarray(mesh.edges)
    vertices, faces = [np.asarray(mesh.vertices)], [np.asarray(mesh.faces)]
    next_vertex = len(mesh.vertices)
    for loop in loops:
        if np.any((directed_edges[:, 0] == loop[0]) & (directed_edges[:, 1] == loop[1])):
            loop = loop[::-1]
        vertices.append(mesh.vertices[loop].mean(axis=0, keepdims=True))
        faces.append(np.column_stack([loop, np.roll(loop, -1), np.full(len(loop), next_vertex)]))
        next_vertex += 1
    filled = trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=False)
    return filled, len(loops)


def _voxel_remesh(mesh: trimesh.Trimesh, path: Path) -> trimesh.Trimesh:
    """Rebuild an open mesh as the solid its axis-aligned rays see, then extract its surface.

    A voxel is solid if, along each of X, Y and Z, it lies between the first and the
    last surface hit of its column. Holes cannot leak (no inside/outside flood fill),
    and everything the front and back renders see along Z is kept.
    """
    pitch = float(np.max(mesh.extents)) / _REPAIR_VOXELS
    low = mesh.bounds[0] - 2.0 * pitch
    shape = np.ceil((mesh.extents + 4.0 * pitch) / pitch).astype(int)
    centres = [low[a] + (np.arange(shape[a]) + 0.5) * pitch for a in range(3)]
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.ascontiguousarray(mesh.vertices, dtype=np.float32)),
        o3d.core.Tensor(np.ascontiguousarray(mesh.faces, dtype=np.uint32)),
    )
    solid = np.ones(shape, dtype=bool)
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        grid_u, grid_v = np.meshgrid(centres[u], centres[v], indexing="ij")
        rays = np.zeros((2,) + grid_u.shape + (6,), dtype=np.float32)
        rays[..., u], rays[..., v] = grid_u, grid_v
        rays[0, ..., axis], rays[0, ..., 3 + axis] = low[axis], 1.0
        rays[1, ..., axis], rays[1, ..., 3 + axis] = low[axis] + shape[axis] * pitch, -1.0
        t_hit = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
        entry, exit_ = low[axis] + t_hit[0], low[axis] + shape[axis] * pitch - t_hit[1]
        along = centres[axis]
        inside = (along[None, None, :] >= entry[..., None]) & (along[None, None, :] <= exit_[..., None])
        solid &= np.moveaxis(inside, 2, axis)  # (u, v, axis) -> x, y, z order
    if np.count_nonzero(solid) < 8:
        raise TemplateError(f"{path.name}: open surface that encloses no volume; cannot be made watertight")
    corners, faces, _, _ = measure.marching_cubes(np.pad(solid, 1).astype(np.float32), 0.5)
    points = low + (corners - 1.0 + 0.5) * pitch
    remeshed = trimesh.Trimesh(points, faces[:, ::-1], process=True)
    trimesh.smoothing.filter_taubin(remeshed, iterations=10)
    return remeshed


def _transfer_labels(
    original: trimesh.Trimesh, labels: np.ndarray, repaired: trimesh.Trimesh, kept: int
) -> np.ndarray:
    """Keep the labels of the first ``kept`` faces; new faces take the nearest original face's."""
    nearest = cKDTree(original.triangles_center).query(repaired.triangles_center[kept:])[1]
    return np.concatenate([labels[:kept], labels[nearest]]).astype(np.int32)


#: Pixel size (width, height) of the contact sheet PNG.
SHEET_SIZE_PX = (1600, 800)

#: (title, rotation taking the view direction onto the renderer's camera axis +Z).
_SHEET_VIEWS = (
    ("front (from +Z) + landmarks", np.eye(4)),
    ("side (from +X; right = -Z)", trimesh.transformations.rotation_matrix(-np.pi / 2, [0, 1, 0])),
    ("top (from +Y; up = -Z)", trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0])),
)

#: Direction to the light of the shaded views: from the upper left, in front.
_LIGHT = np.array([-0.4, 0.5, 1.0]) / np.linalg.norm([-0.4, 0.5, 1.0])


def contact_sheet(template: Template, renders: TemplateRenders, out_png: Path) -> None:
    """One PNG to eyeball a template: three shaded views, depths, normals, regions, landmarks.

    Every map panel is drawn in world coordinates (metres), so landmarks and axes read
    the same on each; both depth panels share one colour scale.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    figure, axes = plt.subplots(2, 4, figsize=(SHEET_SIZE_PX[0] / 100, SHEET_SIZE_PX[1] / 100), dpi=100)
    figure.suptitle(
        f"{template.family} / {template.subtype}: {len(template.mesh.faces)} faces, "
        f"renders {renders.resolution}x{renders.resolution}, pixel {renders.pixel_size * 1000:.2f} mm",
        fontsize=14,
    )
    for axis, (title, rotation) in zip(axes[0, :3], _SHEET_VIEWS):
        shaded, extent = _shaded_view(template.mesh, rotation)
        axis.imshow(shaded, cmap="gray", vmin=0.0, vmax=1.0, extent=extent, interpolation="bilinear")
        axis.set_title(title)
    for name, point in template.landmarks.items():
        axes[0, 0].plot(point[0], point[1], "o", color="tab:red", markersize=6, markeredgecolor="white")
        axes[0, 0].annotate(name, point[:2], xytext=(5, 5), textcoords="offset points", color="tab:red", fontsize=9)

    extent = _grid_extent(renders.center, renders.half_width)
    inside = np.concatenate([renders.front_depth[renders.mask], renders.back_depth[renders.mask]])
    low, high = (float(inside.min()), float(inside.max())) if inside.size else (0.0, 1.0)
    for axis, depth, title in (
        (axes[0, 3], renders.front_depth, "front depth"),
        (axes[1, 0], renders.back_depth, "back depth"),
    ):
        image = axis.imshow(depth, cmap="viridis", vmin=low, vmax=high, extent=extent, interpolation="nearest")
        figure.colorbar(image, ax=axis, fraction=0.046, pad=0.03, label="world Z (m)")
        axis.set_title(title)
    for axis, normals, title in (
        (axes[1, 1], renders.front_normals, "front normals (RGB = XYZ)"),
        (axes[1, 2], renders.back_normals, "back normals (RGB = XYZ)"),
    ):
        colours = np.where(renders.mask[..., None], (normals + 1.0) / 2.0, 1.0)
        axis.imshow(np.clip(colours, 0.0, 1.0), extent=extent, interpolation="nearest")
        axis.set_title(title)

    count = max(len(renders.region_names), 1)
    palette = matplotlib.colormaps["tab10" if count <= 10 else "tab20"](np.arange(count) % 20)
    axes[1, 3].imshow(
        np.where(renders.mask, renders.front_regions, np.nan),
        cmap=ListedColormap(palette),
        vmin=-0.5,
        vmax=count - 0.5,
        extent=extent,
        interpolation="nearest",
    )
    axes[1, 3].set_title("front regions")
    axes[1, 3].legend(
        handles=[Patch(color=palette[i], label=name) for i, name in enumerate(renders.region_names)],
        loc="upper right",
        fontsize=8,
        framealpha=0.85,
    )
    for axis in axes.flat:
        axis.set_aspect("equal")
        axis.tick_params(labelsize=7)
    figure.subplots_adjust(left=0.03, right=0.95, bottom=0.05, top=0.88, wspace=0.42, hspace=0.3)
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out_png, dpi=100)
    plt.close(figure)


def _shaded_view(mesh: trimesh.Trimesh, rotation: np.ndarray, resolution: int = 384) -> tuple[np.ndarray, list[float]]:
    """Lambert-shaded orthographic view of the rotated mesh (white background), and its extent."""
    rotated = mesh.copy()
    rotated.apply_transform(rotation)
    center, half_width = render_grid(rotated)
    front, _ = raycast_front_back(rotated, center, half_width, resolution)
    shade = 0.15 + 0.85 * np.clip(front.normals @ _LIGHT, 0.0, 1.0)
    return np.where(front.hit, shade, 1.0), _grid_extent(center, half_width)


def _grid_extent(center: tuple[float, float], half_width: float) -> list[float]:
    """matplotlib ``extent`` (left, right, bottom, top) of a render grid, in world units."""
    return [center[0] - half_width, center[0] + half_width, center[1] - half_width, center[1] + half_width]
