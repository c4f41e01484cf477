"""The slab baseline: the silhouette extruded to a constant thickness, no template.

It is the bar the template method must clearly beat: anything a template adds (relief,
thickness profile, rounded sides) has to show up as better metrics than this.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import trimesh

from frontal3d.errors import InputError
from frontal3d.masks import mask_extent

#: Slab thickness / the silhouette's longest side, per family. Guitar and car: the
#: median ratio of Z extent to longest image-plane extent of the development meshes
#: (0.069, 0.455). Airplane: the Z extent (0.21) is the tail fin's height, not the
#: body's; a 0.05 slab scores better (IoU 0.35 against 0.18 at the full Z extent).
SLAB_THICKNESS_RATIO = {"guitar": 0.07, "car": 0.45, "airplane": 0.05}


def slab_from_mask(
    mask: np.ndarray,
    pixel_size: float,
    thickness: float,
    origin: tuple[float, float] = (0.0, 0.0),
    z_center: float = 0.0,
) -> trimesh.Trimesh:
    """Extrude the pixels of ``mask`` into a closed slab of the given ``thickness``.

    Built per pixel: a top and a bottom quad for every mask pixel and a side quad for
    every edge between a mask pixel and a background pixel, on shared corner vertices,
    so the slab is closed and its volume is exactly pixel count x pixel area x thickness.
    ``origin`` is the world (x, y) of the centre of pixel (row 0, col 0); rows go down
    (-Y), columns go right (+X), and the slab spans ``z_center +- thickness / 2``.
    """
    mask = np.asarray(mask).astype(bool)
    if mask.ndim != 2 or not mask.any():
        raise InputError("slab baseline needs a non-empty 2D mask")
    if pixel_size <= 0 or thickness <= 0:
        raise InputError("slab baseline needs a positive pixel size and thickness")

    height, width = mask.shape
    padded = np.pad(mask, 1)
    # Corner (i, j) is the top-left corner of pixel (i, j): ids for two layers (z-, z+).
    n_corners = (height + 1) * (width + 1)

    def corner(i: np.ndarray, j: np.ndarray, top: bool) -> np.ndarray:
        return i * (width + 1) + j + (n_corners if top else 0)

    rows, cols = np.nonzero(mask)
    quads = [
        # Top (+Z, counter-clockwise seen from +Z: image y goes down, so clockwise in rows).
        np.stack([corner(rows, cols, True), corner(rows + 1, cols, True),
                  corner(rows + 1, cols + 1, True), corner(rows, cols + 1, True)], axis=1),
        np.stack([corner(rows, cols, False), corner(rows, cols + 1, False),
                  corner(rows + 1, cols + 1, False), corner(rows + 1, cols, False)], axis=1),
    ]
    # Side quads: for each pixel and each of its 4 neighbours outside the mask.
    # Edge a -> b runs so that (b - a) x Z points out of the mask.
    sides = [
        (padded[:-2, 1:-1], (0, 1), (0, 0)),  # neighbour above (+Y): edge along the top
        (padded[2:, 1:-1], (1, 0), (1, 1)),  # below
        (padded[1:-1, :-2], (0, 0), (1, 0)),  # left (-X)
        (padded[1:-1, 2:], (1, 1), (0, 1)),  # right
    ]
    for neighbour, (ai, aj), (bi, bj) in sides:
        r, c = np.nonzero(mask & ~neighbour)
        quads.append(np.stack([corner(r + ai, c + aj, False), corner(r + bi, c + bj, False),
                               corner(r + bi, c + bj, True), corner(r + ai, c + aj, True)], axis=1))
    quads = np.concatenate(quads)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])

    ci, cj = np.divmod(np.arange(n_corners), width + 1)
    x = origin[0] + (cj - 0.5) * pixel_size
    y = origin[1] - (ci - 0.5) * pixel_size
    half = 0.5 * thickness
    vertices = np.concatenate([
        np.stack([x, y, np.full(n_corners, z_center - half)], axis=1),
        np.stack([x, y, np.full(n_corners, z_center + half)], axis=1),
    ])
    slab = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    slab.remove_unreferenced_vertices()
    return slab


def slab_reconstructor(thickness_ratio: float) -> Callable[[np.ndarray, np.ndarray, dict], trimesh.Trimesh]:
    """A ``reconstruct`` callable for :func:`frontal3d.evaluate.run_evaluation` scoring the slab.

    The slab is placed on the render's camera grid (``center``, ``half_width``) and made
    ``thickness_ratio`` x the silhouette's longest side thick, centred at Z = 0.
    """
    if thickness_ratio <= 0:
        raise InputError("slab thickness ratio must be positive")

    def reconstruct(image: np.ndarray, mask: np.ndarray, camera: dict) -> trimesh.Trimesh:
        mask = np.asarray(mask).astype(bool)
        if not mask.any():
            raise InputError("slab baseline got an empty mask")
        pixel_size = 2.0 * float(camera["half_width"]) / mask.shape[1]
        cx, cy = (float(v) for v in camera["center"])
        origin = (cx - camera["half_width"] + 0.5 * pixel_size, cy + camera["half_width"] - 0.5 * pixel_size)
        longest = mask_extent(mask) * pixel_size
        return slab_from_mask(mask, pixel_size, thickness_ratio * longest, origin=origin)

    return reconstruct
