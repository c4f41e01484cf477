"""Building templates as closed height fields: a region-labelled outline plus front/back depth.

Why height fields: the paper asks templates for identical front and back silhouettes,
smooth sides and no cavities (section 3.2.1). A solid described by an outline and a
front and back depth over it has exactly those properties by construction, and meshing
it with the pipeline's own mesher makes it watertight. Outlines are drawn from signed
distance functions, so parts blend with smooth unions and edges round off by distance
to the silhouette.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import manifold3d
import numpy as np
import trimesh

from frontal3d.errors import TemplateError
from frontal3d.family import Template
from frontal3d.stages.mesh import build_mesh


@dataclass
class Canvas:
    """A pixel grid over a world rectangle (metres), image up = +Y, for drawing templates."""

    x_range: tuple[float, float]
    y_range: tuple[float, float]
    pixels_long_side: int = 240
    x: np.ndarray = field(init=False)
    y: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        (x0, x1), (y0, y1) = self.x_range, self.y_range
        self.pixel_size = max(x1 - x0, y1 - y0) / self.pixels_long_side
        cols = int(np.ceil((x1 - x0) / self.pixel_size)) + 4
        rows = int(np.ceil((y1 - y0) / self.pixel_size)) + 4
        self.x0 = (x0 + x1) / 2 - cols * self.pixel_size / 2
        self.y1 = (y0 + y1) / 2 + rows * self.pixel_size / 2
        xs = self.x0 + (np.arange(cols) + 0.5) * self.pixel_size
        ys = self.y1 - (np.arange(rows) + 0.5) * self.pixel_size
        self.x, self.y = np.meshgrid(xs, ys)

    @property
    def shape(self) -> tuple[int, int]:
        return self.x.shape

    def distance_inside(self, mask: np.ndarray) -> np.ndarray:
        """Distance (metres) from each pixel inside ``mask`` to the nearest outside pixel."""
        padded = np.pad(mask.astype(np.uint8), 1)
        return cv2.distanceTransform(padded, cv2.DIST_L2, 5)[1:-1, 1:-1] * self.pixel_size


# Signed distance functions on a canvas: negative inside, metres.
def sd_circle(c: Canvas, cx: float, cy: float, r: float) -> np.ndarray:
    return np.hypot(c.x - cx, c.y - cy) - r


def sd_ellipse(c: Canvas, cx: float, cy: float, rx: float, ry: float) -> np.ndarray:
    """Approximate ellipse distance (exact on the axes; good enough for outlines)."""
    k = np.hypot((c.x - cx) / rx, (c.y - cy) / ry)
    return (k - 1.0) * min(rx, ry)


def sd_box(c: Canvas, x0: float, x1: float, y0: float, y1: float, round_r: float = 0.0) -> np.ndarray:
    """Axis-aligned box with rounded corners of radius ``round_r``."""
    hx, hy = (x1 - x0) / 2 - round_r, (y1 - y0) / 2 - round_r
    qx = np.abs(c.x - (x0 + x1) / 2) - hx
    qy = np.abs(c.y - (y0 + y1) / 2) - hy
    outside = np.hypot(np.maximum(qx, 0), np.maximum(qy, 0))
    return outside + np.minimum(np.maximum(qx, qy), 0) - round_r


def sd_polygon(c: Canvas, points: list[tuple[float, float]], round_r: float = 0.0) -> np.ndarray:
    """A polygon rounded by ``round_r`` (inset then offset with manifold3d's CrossSection)."""
    section = manifold3d.CrossSection([np.asarray(points, dtype=np.float64)], manifold3d.FillRule.NonZero)
    if round_r > 0:
        section = section.offset(-round_r, manifold3d.JoinType.Round).offset(round_r, manifold3d.JoinType.Round, circular_segments=32)
    mask = np.zeros(c.shape, np.uint8)
    for loop in section.to_polygons():
        px = np.stack([(loop[:, 0] - c.x0) / c.pixel_size - 0.5, (c.y1 - loop[:, 1]) / c.pixel_size - 0.5], axis=1)
        cv2.fillPoly(mask, [np.round(px * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    inside = c.distance_inside(mask > 0)
    # Outside distances must not see the canvas edge as a boundary: no padding here.
    outside = cv2.distanceTransform((mask == 0).astype(np.uint8), cv2.DIST_L2, 5) * c.pixel_size
    return np.where(mask > 0, -inside, outside)


def smooth_union(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Union that blends the two outlines over a width ``k`` (no sharp notch where they meet)."""
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b * (1 - h) + a * h - k * h * (1 - h)


def rounded_profile(distance: np.ndarray, half_thickness: np.ndarray | float, radius: float) -> np.ndarray:
    """Half-thickness at each pixel with the edge rounded by a quarter circle of ``radius``.

    ``distance`` is the distance to the silhouette; far from it the half-thickness is
    reached, at the silhouette it is ``half_thickness - radius`` (the side wall).
    """
    half = np.asarray(half_thickness, dtype=np.float64)
    r = np.minimum(radius, half)
    d = np.minimum(distance, r)
    return half - r + np.sqrt(np.maximum(r**2 - (r - d) ** 2, 0.0))


def height_field_template(
    family: str,
    subtype: str,
    canvas: Canvas,
    labels: np.ndarray,
    front_z: np.ndarray,
    back_z: np.ndarray,
    region_names: tuple[str, ...],
    landmarks: dict[str, tuple[float, float, float]],
    smooth_iterations: int = 2,
) -> Template:
    """Mesh a labelled height field into a watertight template centred at its bbox centre."""
    mask = labels >= 0
    result = build_mesh(mask, np.where(mask, front_z, np.nan), np.where(mask, back_z, np.nan), canvas.pixel_size, smooth_iterations=smooth_iterations)
    mesh = result.mesh
    # build_mesh puts pixel (r, c) at x = (c + 0.5) * ps, y = -(r + 0.5) * ps: move to the canvas frame.
    mesh.apply_translation([canvas.x0, canvas.y1, 0.0])
    pixel = np.round(result.vertex_pixel).astype(int)
    vertex_labels = labels[pixel[:, 1], pixel[:, 0]]
    face_labels = _face_labels(mesh.faces, vertex_labels, result.vertex_side)
    centre = mesh.bounds.mean(axis=0)
    mesh.apply_translation(-centre)
    if not mesh.is_watertight or mesh.volume <= 0:
        raise TemplateError(f"template {family}/{subtype} is not a closed solid")
    return Template(
        family=family,
        subtype=subtype,
        mesh=mesh,
        face_regions=face_labels,
        region_names=region_names,
        landmarks={name: np.asarray(p, dtype=np.float64) - centre for name, p in landmarks.items()},
    )


def _face_labels(faces: np.ndarray, vertex_labels: np.ndarray, vertex_side: np.ndarray) -> np.ndarray:
    """A face takes its vertices' most common label (side faces: of their front vertices)."""
    labels = vertex_labels[faces]
    first, second, third = labels[:, 0], labels[:, 1], labels[:, 2]
    return np.where(second == third, second, first).astype(np.int32)


def surface_z(canvas: Canvas, z: np.ndarray, x: float, y: float) -> float:
    """The height-field value at world (x, y) (nearest pixel), for placing landmarks on a surface."""
    col = int(np.clip(round((x - canvas.x0) / canvas.pixel_size - 0.5), 0, canvas.shape[1] - 1))
    row = int(np.clip(round((canvas.y1 - y) / canvas.pixel_size - 0.5), 0, canvas.shape[0] - 1))
    return float(z[row, col])


def as_trimesh_check(template: Template) -> trimesh.Trimesh:
    """The template mesh through manifold3d: raises if it is not a valid 2-manifold solid."""
    mesh = template.mesh
    solid = manifold3d.Manifold(manifold3d.Mesh(vert_properties=np.asarray(mesh.vertices, np.float32), tri_verts=np.asarray(mesh.faces, np.uint32)))
    if solid.status() != manifold3d.Error.NoError:
        raise TemplateError(f"template {template.family}/{template.subtype}: manifold3d rejects it ({solid.status()})")
    return mesh
