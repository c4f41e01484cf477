"""Meshing (paper 3.2.5): turn warped front/back depth maps into one closed solid.

Every mask pixel becomes a front and a back vertex; every 2x2 block of mask pixels
becomes two front and two back triangles; each silhouette edge of that block union
(outer contours and holes alike) gets one side quad joining front to back. Where two
blocks touch only at a corner, the two triangles beside that corner are added, so
every vertex has a single fan and the stitched surface is closed and consistently
oriented by construction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy import sparse

from frontal3d.errors import ConfigError, InputError

SYMMETRY_RULES = ("none", "mirror_z")

#: Weight of the neighbour average in one Laplacian smoothing step.
_SMOOTHING_STEP = 0.5

#: Farthest (in pixel sizes) smoothing may move a vertex in Z. Warp noise is a pixel or
#: two high; anything taller is shape (an airplane's fin seen edge-on from above is a
#: ridge a few pixels wide) and must not be flattened.
MAX_SMOOTHING_SHIFT_PIXELS = 2.0


@dataclass
class MeshResult:
    """The closed mesh plus what the texture stage needs to build UVs.

    ``vertex_pixel[v]`` is the image pixel (x=col, y=row) vertex ``v`` was made from;
    ``vertex_side[v]`` is 0 for the front surface, 1 for the back. Front vertices come
    first, then their back twins in the same order. ``dropped_pixels`` counts mask
    pixels (on the meshed grid) that lie in no 2x2 block of mask pixels: isolated pixels
    and one-pixel-wide lines or diagonal chains, the only places the silhouette changes.
    """

    mesh: trimesh.Trimesh
    vertex_pixel: np.ndarray
    vertex_side: np.ndarray
    dropped_pixels: int


def mesh_cells(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 2x2 blocks and corner-pinch fill triangles to mesh, as pixel (row, col) triples.

    Returns ``blocks`` ((H-1, W-1) bool, block (r, c) = pixels r..r+1, c..c+1, kept when
    all four are in the mask) and ``fills`` ((n, 3, 2) int). Two blocks that share only
    a corner pixel v would make v a non-manifold vertex; the two windows beside them
    each have three mask pixels, so each gets the triangle around v, which closes the
    fan at v. The triangles only use mask pixels, so the silhouette does not change.
    """
    blocks = mask[:-1, :-1] & mask[1:, :-1] & mask[:-1, 1:] & mask[1:, 1:]
    top_left, top_right = blocks[:-1, :-1], blocks[:-1, 1:]
    bottom_left, bottom_right = blocks[1:, :-1], blocks[1:, 1:]
    fills = []
    for pinch, first, second in (
        (top_left & bottom_right & ~top_right & ~bottom_left, ((-1, 0), (0, 1)), ((0, -1), (1, 0))),
        (top_right & bottom_left & ~top_left & ~bottom_right, ((-1, 0), (0, -1)), ((0, 1), (1, 0))),
    ):
        centre = np.argwhere(pinch) + 1
        for offsets in (first, second):
            fills.append(np.stack([centre + offsets[0], centre, centre + offsets[1]], axis=1))
    return blocks, np.concatenate(fills)


def _block_pixels(blocks: np.ndarray) -> np.ndarray:
    """Pixels that are a corner of at least one kept block."""
    used = np.zeros((blocks.shape[0] + 1, blocks.shape[1] + 1), dtype=bool)
    used[:-1, :-1] |= blocks
    used[1:, :-1] |= blocks
    used[:-1, 1:] |= blocks
    used[1:, 1:] |= blocks
    return used


def _smoothing_operator(front_faces: np.ndarray, count: int) -> sparse.csr_matrix:
    """Row-normalised adjacency of the front grid: one application = neighbour mean."""
    edges = np.concatenate([front_faces[:, [0, 1]], front_faces[:, [1, 2]], front_faces[:, [2, 0]]])
    edges = np.concatenate([edges, edges[:, ::-1]])
    adjacency = sparse.csr_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(count, count))
    adjacency.data[:] = 1.0
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return sparse.diags(1.0 / degree) @ adjacency


def _separate(front: np.ndarray, back: np.ndarray, min_thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """Push front and back apart about their midpoint wherever they are closer than ``min_thickness``."""
    thin = back > front - min_thickness
    middle = 0.5 * (front + back)
    return np.where(thin, middle + 0.5 * min_thickness, front), np.where(thin, middle - 0.5 * min_thickness, back)


def _triangulate(
    mask: np.ndarray,
    front_z: np.ndarray,
    back_z: np.ndarray,
    stride: int,
    pixel_size: float,
    smooth_iterations: int,
    min_thickness: float,
) -> MeshResult:
    """Mesh the pixels ``mask[::stride, ::stride]``; vertices keep full-grid pixel coordinates."""
    sub_mask = mask[::stride, ::stride]
    blocks, fills = mesh_cells(sub_mask)
    used = _block_pixels(blocks)
    count = int(used.sum())
    if count == 0:
        raise InputError("mask has no 2x2 block of object pixels: nothing to mesh")
    rows, cols = np.nonzero(used)
    front = np.asarray(front_z, dtype=np.float64)[::stride, ::stride][rows, cols]
    back = np.asarray(back_z, dtype=np.float64)[::stride, ::stride][rows, cols]
    bad = ~(np.isfinite(front) & np.isfinite(back))
    if bad.any():
        raise InputError(f"depth maps are NaN or infinite at {int(bad.sum())} pixels inside the mask")

    index = np.full(used.shape, -1, dtype=np.int64)
    index[rows, cols] = np.arange(count)
    block_rows, block_cols = np.nonzero(blocks)
    # Block corners: a top-left, b top-right, c bottom-left, d bottom-right (image up = +Y),
    # so (a, c, d) and (a, d, b) are counter-clockwise seen from the camera.
    a = index[block_rows, block_cols]
    b = index[block_rows, block_cols + 1]
    c = index[block_rows + 1, block_cols]
    d = index[block_rows + 1, block_cols + 1]
    fill_faces = index[fills[..., 0], fills[..., 1]]
    fill_rows = fills[..., 0].astype(np.float64)
    fill_cols = fills[..., 1].astype(np.float64)
    clockwise = (fill_cols[:, 1] - fill_cols[:, 0]) * (fill_rows[:, 0] - fill_rows[:, 2]) < (
        (fill_rows[:, 0] - fill_rows[:, 1]) * (fill_cols[:, 2] - fill_cols[:, 0])
    )
    fill_faces[clockwise] = fill_faces[clockwise][:, ::-1]
    front_faces = np.concatenate([np.stack([a, c, d], 1), np.stack([a, d, b], 1), fill_faces])
    back_faces = front_faces[:, ::-1] + count

    # Silhouette edges are the front edges used by one face only; keeping their
    # direction from the counter-clockwise faces orients the side quads outwards.
    directed = np.concatenate([front_faces[:, [0, 1]], front_faces[:, [1, 2]], front_faces[:, [2, 0]]])
    keys = np.minimum(directed[:, 0], directed[:, 1]) * count + np.maximum(directed[:, 0], directed[:, 1])
    _, first, uses = np.unique(keys, return_index=True, return_counts=True)
    starts, ends = directed[first[uses == 1]].T
    side_faces = np.concatenate(
        [np.stack([ends, starts, starts + count], 1), np.stack([ends, starts + count, ends + count], 1)]
    )

    front, back = _separate(front, back, min_thickness)
    if smooth_iterations > 0:
        neighbour_mean = _smoothing_operator(front_faces, count)
        warped = np.stack([front, back], axis=1)
        depths = warped
        for _ in range(smooth_iterations):
            depths = (1.0 - _SMOOTHING_STEP) * depths + _SMOOTHING_STEP * (neighbour_mean @ depths)
        reach = MAX_SMOOTHING_SHIFT_PIXELS * pixel_size
        depths = warped + np.clip(depths - warped, -reach, reach)
        front, back = _separate(depths[:, 0], depths[:, 1], min_thickness)

    pixel_cols = (cols * stride).astype(np.float64)
    pixel_rows = (rows * stride).astype(np.float64)
    x = (pixel_cols + 0.5) * pixel_size
    y = -(pixel_rows + 0.5) * pixel_size
    vertices = np.concatenate([np.stack([x, y, front], 1), np.stack([x, y, back], 1)])
    faces = np.concatenate([front_faces, back_faces, side_faces])
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    vertex_pixel = np.tile(np.stack([pixel_cols, pixel_rows], 1), (2, 1))
    vertex_side = np.repeat(np.array([0, 1], dtype=np.int8), count)
    return MeshResult(mesh, vertex_pixel, vertex_side, int(sub_mask.sum()) - count)


def build_mesh(
    mask: np.ndarray,
    front_z: np.ndarray,
    back_z: np.ndarray,
    pixel_size: float,
    smooth_iterations: int = 10,
    max_vertices: int | None = None,
    min_thickness: float | None = None,
) -> MeshResult:
    """Closed, outward-oriented mesh of the object from its front and back depth maps.

    Vertex (x, y) = ((col + 0.5) * pixel_size, -(row + 0.5) * pixel_size), z = depth:
    the caller has already rescaled depth to the image's units. The back is kept at
    least ``min_thickness`` (default one ``pixel_size``) behind the front. Smoothing
    moves z only, so the silhouette and the pixel each vertex came from stay exact.
    ``max_vertices`` meshes every n-th pixel instead of decimating: the coarser grid is
    built the same way, so it stays watertight.
    """
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise InputError(f"mask must be a 2D array, got shape {mask.shape}")
    mask = mask.astype(bool)
    if np.shape(front_z) != mask.shape or np.shape(back_z) != mask.shape:
        raise InputError(
            f"depth maps {np.shape(front_z)} and {np.shape(back_z)} do not match the mask {mask.shape}"
        )
    if not pixel_size > 0:
        raise InputError(f"pixel size must be positive, got {pixel_size}")
    if max_vertices is not None and max_vertices < 8:
        raise ConfigError(f"max_vertices must be at least 8, got {max_vertices}")
    thickness = pixel_size if min_thickness is None else float(min_thickness)

    stride = 1
    if max_vertices is not None:
        stride = max(1, int(np.sqrt(2 * mask.sum() / max_vertices)))
    while True:
        result = _triangulate(mask, front_z, back_z, stride, pixel_size, smooth_iterations, thickness)
        if max_vertices is None or len(result.vertex_side) <= max_vertices:
            return result
        stride += 1


def apply_symmetry(
    front_z: np.ndarray, back_z: np.ndarray, mask: np.ndarray, rule: str
) -> tuple[np.ndarray, np.ndarray]:
    """Apply a family's symmetry rule to the warped depth maps.

    ``none`` keeps the template's back. ``mirror_z`` makes the hidden side mirror the
    visible one across the object's mid plane (a car seen from the side is as wide on
    the far side as on the near one): back = 2 * mid - front, with mid the median over
    the mask of (front + back) / 2. Outside the mask the maps are returned unchanged.
    """
    if rule not in SYMMETRY_RULES:
        raise ConfigError(f"unknown symmetry rule {rule!r}; expected one of {SYMMETRY_RULES}")
    front_z = np.array(front_z, dtype=np.float64)
    back_z = np.array(back_z, dtype=np.float64)
    if rule == "none":
        return front_z, back_z
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        raise InputError("mask is empty: no mid plane to mirror about")
    mid = np.median(0.5 * (front_z[mask] + back_z[mask]))
    back_z[mask] = 2.0 * mid - front_z[mask]
    return front_z, back_z
