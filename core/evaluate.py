"""The paper's evaluation protocol (section 4) and the evaluate/bench drivers.

Protocol, as in the paper:

* **IoU** -- centre each mesh at its bounding-box centre and scale its longest side to 1,
  voxelize both on the same 128^3 grid, fill the inside, align the two voxel sets by ICP
  and take the IoU of the aligned occupancies.
* **Chamfer-L1 / F-score** -- scale each *original* mesh so that 1/10 of its own longest
  bounding-box edge is the unit (longest edge = 10), centred, sample 10K surface points
  from each, and compare: accuracy = mean distance pred->gt, completeness = gt->pred,
  Chamfer-L1 = their mean, F = harmonic mean of precision and recall at 0.1 (1 % of the
  side).

Two choices the paper leaves open, and what this module does:

* Filling. Ground-truth meshes are mostly not watertight, so an inside/outside test by
  ray parity or a flood fill from outside would leak through the holes and leave a
  hollow shell. The surface voxels are closed by one 3x3x3 closing (seals one-voxel
  gaps) and then filled *orthographically*: a voxel is inside when a surface voxel lies
  on each of the six axis-aligned rays leaving it. A hole then only opens the few rays
  that pass through it, and the frontal families (car side view, airplane planform,
  guitar face) have no pockets closed off along all six axes, where this fill would
  over-fill.
* Alignment of the points. The paper aligns the voxelizations for the IoU and then
  "scales each original mesh" for the point metrics, so the point metrics are taken
  without the ICP transform (each mesh centred at its own bounding-box centre). Both
  meshes of a pair come from the same canonical frame, so the rotation ICP could add is
  only what the IoU needs to forgive voxel-level misplacement.
"""

from __future__ import annotations

import csv
import json
import math
import statistics
import time
import traceback
from collections.abc import Callable
from pathlib import Path

import numpy as np
import open3d as o3d
import trimesh
from scipy import ndimage
from scipy.spatial import cKDTree

from frontal3d.errors import InputError

#: Resolution and side of the voxel grid the paper's IoU uses (normalized units).
VOXEL_RESOLUTION = 128
#: ICP only pairs voxels this close (normalized units, ~13 voxels at 128^3).
ICP_MAX_DISTANCE = 0.1
#: Longest bounding-box edge of both meshes for the point metrics (unit = 1/10 of it).
POINT_SCALE = 10.0

Reconstruct = Callable[[np.ndarray, np.ndarray, dict], trimesh.Trimesh]


# --------------------------------------------------------------------------- metrics


def _check_mesh(mesh: trimesh.Trimesh, role: str) -> None:
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError(f"{role} mesh is empty or not a triangle mesh")
    if float(np.max(mesh.extents)) <= 0.0 or not np.all(np.isfinite(mesh.vertices)):
        raise InputError(f"{role} mesh has a degenerate or non-finite bounding box")


def _scaled(mesh: trimesh.Trimesh, longest_side: float) -> trimesh.Trimesh:
    """Copy of ``mesh`` centred at its bounding-box centre, longest bbox edge = ``longest_side``."""
    centre = mesh.bounds.mean(axis=0)
    vertices = (mesh.vertices - centre) * (longest_side / float(np.max(mesh.extents)))
    return trimesh.Trimesh(vertices=vertices, faces=mesh.faces, process=False)


def normalize(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Centre ``mesh`` at its bounding-box centre and scale its longest side to 1.

    This is the paper's first step: it removes the position and size of a prediction so
    only its shape is judged.
    """
    _check_mesh(mesh, "input")
    return _scaled(mesh, 1.0)


def _grid_centres(resolution: int) -> np.ndarray:
    """Voxel centre coordinates along one axis of the padded grid over [-0.5, 0.5]."""
    pitch = 1.0 / resolution
    return (np.arange(resolution + 2) - 0.5) * pitch - 0.5


def voxelize_filled(mesh: trimesh.Trimesh, resolution: int = VOXEL_RESOLUTION) -> np.ndarray:
    """Solid occupancy of a *normalized* mesh on a (resolution + 2)^3 grid over [-0.5, 0.5]^3.

    The grid has a one-voxel empty border so the fill sees an outside on every side.
    Filling is the orthographic one described in the module docstring.
    """
    pitch = 1.0 / resolution
    o3d_mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(np.asarray(mesh.vertices, dtype=np.float64)),
        o3d.utility.Vector3iVector(np.asarray(mesh.faces, dtype=np.int32)),
    )
    lower = np.full(3, -0.5 - pitch)
    upper = np.full(3, 0.5 + pitch)
    grid = o3d.geometry.VoxelGrid.create_from_triangle_mesh_within_bounds(o3d_mesh, pitch, lower, upper)
    surface = np.zeros((resolution + 2,) * 3, dtype=bool)
    indices = np.array([v.grid_index for v in grid.get_voxels()], dtype=np.int64).reshape(-1, 3)
    indices = np.clip(indices, 0, resolution + 1)
    surface[indices[:, 0], indices[:, 1], indices[:, 2]] = True

    surface = ndimage.binary_closing(surface, structure=np.ones((3, 3, 3), bool)) | surface
    inside = np.ones_like(surface)
    for axis in range(3):
        before = np.logical_or.accumulate(surface, axis=axis)
        after = np.flip(np.logical_or.accumulate(np.flip(surface, axis=axis), axis=axis), axis=axis)
        inside &= before & after
    return inside | surface


def _boundary_points(occupancy: np.ndarray, resolution: int) -> np.ndarray:
    """Centres (normalized units) of the occupied voxels that touch an empty one."""
    shell = occupancy & ~ndimage.binary_erosion(occupancy)
    centres = _grid_centres(resolution)
    idx = np.nonzero(shell)
    return np.stack([centres[idx[0]], centres[idx[1]], centres[idx[2]]], axis=1)


def _aligned_intersection(pred: np.ndarray, gt: np.ndarray, transform: np.ndarray, resolution: int) -> int:
    """|T(pred) & gt|, resampling pred through T^-1 at every gt voxel centre (no holes)."""
    centres = _grid_centres(resolution)
    gi = np.nonzero(gt)
    points = np.stack([centres[gi[0]], centres[gi[1]], centres[gi[2]]], axis=1)
    rotation, translation = transform[:3, :3], transform[:3, 3]
    source = (points - translation) @ rotation  # R^T (p - t) for row vectors
    index = np.rint((source + 0.5) * resolution + 0.5).astype(np.int64)
    inside = np.all((index >= 0) & (index < resolution + 2), axis=1)
    hits = pred[index[inside, 0], index[inside, 1], index[inside, 2]]
    return int(np.count_nonzero(hits))


def _iou_from(pred: np.ndarray, gt: np.ndarray, transform: np.ndarray, resolution: int) -> float:
    inter = _aligned_intersection(pred, gt, transform, resolution)
    union = int(pred.sum()) + int(gt.sum()) - inter
    return inter / union if union else 1.0


def voxel_iou(pred: trimesh.Trimesh, gt: trimesh.Trimesh, resolution: int = VOXEL_RESOLUTION) -> float:
    """IoU of the filled 128^3 voxelizations of the normalized meshes after ICP alignment.

    ICP (open3d, point-to-point, rotation + translation, from identity) runs on the
    boundary voxel centres; the result is kept only if it improves on identity, since
    the paper aligns "to maximize their overlap". Pred's volume is counted as its voxel
    count, so voxels the transform moves off the grid still count in the union.
    """
    _check_mesh(pred, "predicted")
    _check_mesh(gt, "ground-truth")
    pred_occ = voxelize_filled(normalize(pred), resolution)
    gt_occ = voxelize_filled(normalize(gt), resolution)
    identity = np.eye(4)
    best = _iou_from(pred_occ, gt_occ, identity, resolution)

    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(_boundary_points(pred_occ, resolution)))
    target = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(_boundary_points(gt_occ, resolution)))
    result = o3d.pipelines.registration.registration_icp(
        source,
        target,
        ICP_MAX_DISTANCE,
        identity,
        o3d.pipelines.registration.TransformationEstimationPointToPoint(),
        o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=50),
    )
    aligned = _iou_from(pred_occ, gt_occ, np.asarray(result.transformation), resolution)
    return max(best, aligned)


def _surface_points(mesh: trimesh.Trimesh, n_points: int, seed: int) -> np.ndarray:
    points, _ = trimesh.sample.sample_surface(mesh, n_points, seed=seed)
    return np.asarray(points)


def chamfer_f(
    pred: trimesh.Trimesh,
    gt: trimesh.Trimesh,
    n_points: int = 10_000,
    threshold: float = 0.1,
    seed: int = 0,
) -> tuple[float, float]:
    """Chamfer-L1 and F-score (0..1) with each mesh's longest bbox edge scaled to 10.

    Both meshes are sampled with the same seed so that identical meshes compare as 0 / 1.
    Distances are Euclidean (not squared), as in Occupancy Networks' Chamfer-L1.
    """
    _check_mesh(pred, "predicted")
    _check_mesh(gt, "ground-truth")
    pred_points = _surface_points(_scaled(pred, POINT_SCALE), n_points, seed)
    gt_points = _surface_points(_scaled(gt, POINT_SCALE), n_points, seed)
    to_gt, _ = cKDTree(gt_points).query(pred_points)
    to_pred, _ = cKDTree(pred_points).query(gt_points)
    accuracy, completeness = float(to_gt.mean()), float(to_pred.mean())
    precision = float(np.mean(to_gt < threshold))
    recall = float(np.mean(to_pred < threshold))
    fscore = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    return 0.5 * (accuracy + completeness), fscore


def evaluate_pair(pred: trimesh.Trimesh, gt: trimesh.Trimesh, seed: int = 0) -> dict[str, float]:
    """All three paper metrics for one prediction: ``iou``, ``chamfer_l1``, ``fscore`` (0..1)."""
    chamfer, fscore = chamfer_f(pred, gt, seed=seed)
    return {"iou": voxel_iou(pred, gt), "chamfer_l1": chamfer, "fscore": fscore}
