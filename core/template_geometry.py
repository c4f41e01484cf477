"""Shared geometry for building family templates by code.

Templates must have the same silhouette seen from the front and from the back
(paper, section 3.2.1): every ray along -Z should enter the solid once and leave
once. The builders here only make solids with that property: lofts whose rings
are stacked without folding, and "rounded slabs" (a flat-faced plate whose rim is
rounded by offsetting the outline inwards along its normals). Parts are joined
with manifold3d booleans, which carry each part's original id through the union,
so faces are labelled per part without any geometric guessing.
"""

from __future__ import annotations

from collections.abc import Sequence

import manifold3d
import numpy as np
import trimesh

from frontal3d.errors import TemplateError


def chaikin_closed(control: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Smooth a closed control polygon by corner cutting (a quadratic B-spline).

    Corner cutting never overshoots the control polygon, so outlines stay where
    they were drawn, and the result has no sharp corners for the rim offset to fold on.
    """
    points = np.asarray(control, dtype=np.float64)
    for _ in range(iterations):
        following = np.roll(points, -1, axis=0)
        points = np.stack([0.75 * points + 0.25 * following, 0.25 * points + 0.75 * following], axis=1).reshape(-1, 2)
    return points


def resample_closed(points: np.ndarray, count: int) -> np.ndarray:
    """Resample a closed 2D curve to ``count`` points evenly spaced by arc length, counter-clockwise."""
    points = np.asarray(points, dtype=np.float64)
    if polygon_area(points) < 0:
        points = points[::-1]
    closed = np.vstack([points, points[:1]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    targets = np.linspace(0.0, arc[-1], count, endpoint=False)
    return np.stack([np.interp(targets, arc, closed[:, 0]), np.interp(targets, arc, closed[:, 1])], axis=1)


def polygon_area(points: np.ndarray) -> float:
    """Signed area of a closed 2D polygon (positive when counter-clockwise)."""
    x, y = np.asarray(points, dtype=np.float64).T
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def smooth_outline(control: np.ndarray, count: int = 256) -> np.ndarray:
    """A smooth, evenly sampled, counter-clockwise outline from a rough control polygon."""
    return resample_closed(chaikin_closed(control), count)


def rounded_polygon(points: np.ndarray, corner_radius: float, count: int = 256) -> np.ndarray:
    """A polygon with every corner rounded to ``corner_radius``, evenly resampled, counter-clockwise.

    Rounding by shrinking then growing (manifold3d offsets) bounds the convex
    curvature, so a rim of radius up to ``corner_radius`` can be offset inside it.
    """
    section = manifold3d.CrossSection([np.asarray(points, dtype=np.float64)], manifold3d.FillRule.NonZero)
    section = section.offset(-corner_radius, manifold3d.JoinType.Round, circular_segments=64)
    section = section.offset(corner_radius, manifold3d.JoinType.Round, circular_segments=64)
    loops = section.to_polygons()
    if len(loops) != 1:
        raise TemplateError("template outline splits into several pieces when its corners are rounded")
    return resample_closed(np.asarray(loops[0]), count)


def ellipse_outline(centre: tuple[float, float], radii: tuple[float, float], count: int = 128) -> np.ndarray:
    """An evenly parameterised counter-clockwise ellipse."""
    angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    return np.column_stack([centre[0] + radii[0] * np.cos(angle), centre[1] + radii[1] * np.sin(angle)])


def fit_outline(outline: np.ndarray, x_range: tuple[float, float], y_range: tuple[float, float]) -> np.ndarray:
    """Scale and move an outline so its bounding box is exactly ``x_range`` x ``y_range``."""
    low, high = outline.min(axis=0), outline.max(axis=0)
    unit = (outline - low) / (high - low)
    return np.column_stack([x_range[0] + unit[:, 0] * (x_range[1] - x_range[0]), y_range[0] + unit[:, 1] * (y_range[1] - y_range[0])])


def mirrored_outline(right_half: np.ndarray, count: int = 256) -> np.ndarray:
    """A smooth outline symmetric about X = 0 from control points of its right half (bottom to top)."""
    right_half = np.asarray(right_half, dtype=np.float64)
    left_half = right_half[::-1] * np.array([-1.0, 1.0])
    control = np.vstack([right_half, left_half])
    return smooth_outline(control, count)


def inward_normals(outline: np.ndarray) -> np.ndarray:
    """Unit normals pointing into a counter-clockwise closed outline."""
    tangent = np.roll(outline, -1, axis=0) - np.roll(outline, 1, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)


def _cap_triangles(ring: np.ndarray, offset: int, follow_ring_order: bool) -> np.ndarray:
    """Triangulate a planar ring, oriented so its boundary runs with (or against) the ring order."""
    centred = ring - ring.mean(axis=0)
    axes = np.linalg.svd(centred, full_matrices=False)[2][:2]
    flat = centred @ axes.T
    if polygon_area(flat) < 0:
        flat = flat * np.array([1.0, -1.0])
    triangles = np.asarray(manifold3d.triangulate([flat]), dtype=np.int64)
    # Triangles come back counter-clockwise in the projection, i.e. along the ring order.
    if not follow_ring_order:
        triangles = triangles[:, ::-1]
    return triangles + offset


def loft(rings: Sequence[np.ndarray]) -> manifold3d.Manifold:
    """A closed solid through a sequence of rings with equal point counts, capped at both ends.

    Ring ``k`` point ``i`` is joined to ring ``k + 1`` point ``i``: the caller keeps
    the correspondence fold-free (same start point, same direction).
    """
    stack = np.stack([np.asarray(r, dtype=np.float64) for r in rings])
    ring_count, point_count, _ = stack.shape
    index = np.arange(ring_count * point_count).reshape(ring_count, point_count)
    a = index[:-1]
    b = np.roll(index[:-1], -1, axis=1)
    c = np.roll(index[1:], -1, axis=1)
    d = index[1:]
    sides = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    start_cap = _cap_triangles(stack[0], 0, follow_ring_order=False)
    end_cap = _cap_triangles(stack[-1], int(index[-1, 0]), follow_ring_order=True)
    vertices = stack.reshape(-1, 3)
    faces = np.concatenate([sides, start_cap, end_cap])
    solid = manifold3d.Manifold(manifold3d.Mesh64(vert_properties=vertices, tri_verts=faces.astype(np.uint32)))
    if solid.is_empty():
        raise TemplateError("template part is not a closed 2-manifold (bad loft rings)")
    if solid.volume() < 0:
        solid = manifold3d.Manifold(manifold3d.Mesh64(vert_properties=vertices, tri_verts=faces[:, ::-1].astype(np.uint32)))
    return solid.as_original()


def rim_profile(fraction: np.ndarray, floor: float) -> np.ndarray:
    """Relative thickness at a fraction (0 = edge, 1 = rounding radius) of the way in from the rim.

    Elliptical like a rounded edge: vertical tangent at the rim (height ``floor``),
    flat where it meets the face.
    """
    fraction = np.clip(fraction, 0.0, 1.0)
    return floor + (1.0 - floor) * np.sqrt(1.0 - (1.0 - fraction) ** 2)


def rounded_slab(
    outline: np.ndarray,
    z_low: float,
    z_high: float,
    radius: float,
    floor: float = 0.35,
    rings: int = 6,
) -> manifold3d.Manifold:
    """A plate with the given XY outline, flat faces at ``z_low``/``z_high`` and a rounded rim.

    The rim is made by offsetting the outline inwards along its normals up to
    ``radius``; at the outline itself the plate is ``floor`` times its full
    thickness. The silhouette along Z is exactly the outline, front and back.
    Convex corners sharper than ``radius`` are rounded off first.
    """
    # Round convex corners to at least the rim radius, or the inner rings would fold.
    outline = rounded_polygon(outline, 1.05 * radius, count=len(outline))
    normals = inward_normals(outline)
    middle = 0.5 * (z_low + z_high)
    half = 0.5 * (z_high - z_low)
    fractions = np.linspace(0.0, 1.0, rings) ** 1.5
    lower, upper = [], []
    for fraction in fractions:
        xy = outline + normals * (fraction * radius)
        height = half * rim_profile(np.array(fraction), floor)
        lower.append(np.column_stack([xy, np.full(len(xy), middle - height)]))
        upper.append(np.column_stack([xy, np.full(len(xy), middle + height)]))
    return loft(lower[::-1] + upper)


def airfoil(count: int, thickness_ratio: float) -> np.ndarray:
    """A symmetric airfoil loop, chord from 0 (leading edge) to 1, thickness as a chord fraction.

    Uses the NACA 4-digit thickness law with a closed trailing edge; points run
    counter-clockwise with the leading edge at index 0.
    """
    angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    x = 0.5 * (1.0 - np.cos(angle))
    half = 5.0 * thickness_ratio * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1036 * x**4)
    half = np.maximum(half, 1e-4)
    return np.column_stack([x, np.where(angle < np.pi, -half, half)])


def union_labelled(
    parts: Sequence[tuple[manifold3d.Manifold, int]],
    cutters: Sequence[tuple[manifold3d.Manifold, int]] = (),
    decals: Sequence[tuple[manifold3d.Manifold, int]] = (),
) -> tuple[trimesh.Trimesh, np.ndarray]:
    """Union parts, subtract cutters, imprint decals; label every face with its source's region.

    A cutter's faces (the walls and floor of a recess) take the cutter's region.
    A decal is a prism: the solid's surface inside it is split off and relabelled,
    with no change of shape. That is how painted regions (pickups, windows,
    lights) get exact outlines on flat faces that are only a few triangles.
    """
    region_of_id = {}

    def register(solid: manifold3d.Manifold, region: int) -> manifold3d.Manifold:
        solid = solid.as_original()
        region_of_id[solid.original_id()] = region
        return solid

    union = manifold3d.Manifold.batch_boolean([register(s, r) for s, r in parts], manifold3d.OpType.Add)
    for solid, region in cutters:
        union = union - register(solid, region)
    for prism, region in decals:
        union = (union - register(prism, region)) + register(union ^ prism, region)
    mesh_gl = union.to_mesh64()
    vertices = np.asarray(mesh_gl.vert_properties)[:, :3]
    faces = np.asarray(mesh_gl.tri_verts, dtype=np.int64)
    labels = np.full(len(faces), -1, dtype=np.int32)
    run_index = np.asarray(mesh_gl.run_index, dtype=np.int64)
    for run, original in enumerate(np.asarray(mesh_gl.run_original_id)):
        labels[run_index[run] // 3 : run_index[run + 1] // 3] = region_of_id.get(int(original), -1)
    if (labels < 0).any():
        raise TemplateError("template union produced faces with no source part")
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    return mesh, labels


def prism(polygon_xy: np.ndarray, z_low: float, z_high: float) -> manifold3d.Manifold:
    """A straight prism over a 2D polygon (any winding), for decals and cut-outs."""
    polygon = np.asarray(polygon_xy, dtype=np.float64)
    if polygon_area(polygon) < 0:
        polygon = polygon[::-1]
    return loft([np.column_stack([polygon, np.full(len(polygon), z)]) for z in (z_low, z_high)])


def centre_on_bounds(mesh: trimesh.Trimesh, landmarks: dict[str, np.ndarray]) -> tuple[trimesh.Trimesh, dict[str, np.ndarray]]:
    """Move a template so its bounding-box centre is the origin (the shared-data convention)."""
    shift = -0.5 * (mesh.bounds[0] + mesh.bounds[1])
    moved = trimesh.Trimesh(vertices=mesh.vertices + shift, faces=mesh.faces, process=False)
    return moved, {name: np.asarray(point, dtype=np.float64) + shift for name, point in landmarks.items()}


def taper_depth(
    mesh: trimesh.Trimesh, landmarks: dict[str, np.ndarray], y_start: float, y_end: float, end_factor: float
) -> tuple[trimesh.Trimesh, dict[str, np.ndarray]]:
    """Scale Z by a factor rising linearly from 1 at ``y_start`` to ``end_factor`` at ``y_end``.

    Real bodies are rarely equally deep everywhere (an acoustic guitar is deeper at the
    tail than at the neck). Scaling Z about Z = 0 by a positive factor that depends on Y
    only keeps every ray along -Z crossing the solid once, so the template stays valid
    and watertight; outside [y_start, y_end] the factor is clamped (1 before, end after).
    """
    if not end_factor > 0 or y_start == y_end:
        raise TemplateError(f"depth taper needs a positive factor and distinct ends, got {end_factor}, {y_start}..{y_end}")

    def factor(y: np.ndarray) -> np.ndarray:
        return 1.0 + (end_factor - 1.0) * np.clip((y - y_start) / (y_end - y_start), 0.0, 1.0)

    vertices = np.array(mesh.vertices, dtype=np.float64)
    vertices[:, 2] *= factor(vertices[:, 1])
    tapered = {}
    for name, point in landmarks.items():
        point = np.array(point, dtype=np.float64)
        point[2] *= factor(point[1])
        tapered[name] = point
    return trimesh.Trimesh(vertices=vertices, faces=mesh.faces, process=False), tapered
