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
  only what the IoU needs to forgive voxel-level misplacement. Because the other reading
  (the IoU's ICP transform carried over to the point metrics) is just as literal and
  changes the figures of thin objects a lot (an airplane whose fin height is off shifts
  its whole wing plane against the bounding-box centre), :func:`evaluate_pair` also
  reports ``chamfer_l1_icp`` and ``fscore_icp``; the headline figures stay the strict ones.
  :func:`comparison_sheet` (``evaluate -v``) pictures that frame: where a wing plane sits.
"""

from __future__ import annotations

import csv
import json
import statistics
import time
import traceback
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import open3d as o3d
import trimesh
from scipy import ndimage
from scipy.spatial import cKDTree

from frontal3d.errors import ConfigError, InputError
from frontal3d.photo_render import frontal_camera
from frontal3d.photo_render import render_frontal as photo_render_frontal
from frontal3d.progress import counter

#: Resolution and side of the voxel grid the paper's IoU uses (normalized units).
VOXEL_RESOLUTION = 128
#: Offset (in voxels) of the mesh against the grid, irregular so no face sits on a voxel plane.
GRID_JITTER = np.array([0.0137, 0.0071, 0.0113])
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
    # Axis-aligned faces lying exactly on a voxel boundary (slabs, boxes) are dropped by
    # open3d's triangle-box test; a tiny, irregular offset keeps every face off the planes.
    vertices = np.asarray(mesh.vertices, dtype=np.float64) + GRID_JITTER * pitch
    o3d_mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(vertices),
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
    return aligned_voxel_iou(pred, gt, resolution)[0]


def aligned_voxel_iou(pred: trimesh.Trimesh, gt: trimesh.Trimesh, resolution: int = VOXEL_RESOLUTION) -> tuple[float, np.ndarray]:
    """:func:`voxel_iou` and the 4x4 transform (normalized units) it kept for ``pred``."""
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
    transform = np.asarray(result.transformation)
    aligned = _iou_from(pred_occ, gt_occ, transform, resolution)
    return (aligned, transform) if aligned > best else (best, identity)


def _surface_points(mesh: trimesh.Trimesh, n_points: int, seed: int) -> np.ndarray:
    points, _ = trimesh.sample.sample_surface(mesh, n_points, seed=seed)
    return np.asarray(points)


def chamfer_f(
    pred: trimesh.Trimesh,
    gt: trimesh.Trimesh,
    n_points: int = 10_000,
    threshold: float = 0.1,
    seed: int = 0,
    pred_transform: np.ndarray | None = None,
) -> tuple[float, float]:
    """Chamfer-L1 and F-score (0..1) with each mesh's longest bbox edge scaled to 10.

    Both meshes are sampled with the same seed so that identical meshes compare as 0 / 1.
    Distances are Euclidean (not squared), as in Occupancy Networks' Chamfer-L1.
    ``pred_transform`` (4x4, normalized units, e.g. the IoU's ICP) moves the prediction first.
    """
    _check_mesh(pred, "predicted")
    _check_mesh(gt, "ground-truth")
    pred_points = _surface_points(_scaled(pred, POINT_SCALE), n_points, seed)
    if pred_transform is not None:
        pred_points = pred_points @ pred_transform[:3, :3].T + POINT_SCALE * pred_transform[:3, 3]
    gt_points = _surface_points(_scaled(gt, POINT_SCALE), n_points, seed)
    to_gt, _ = cKDTree(gt_points).query(pred_points)
    to_pred, _ = cKDTree(pred_points).query(gt_points)
    accuracy, completeness = float(to_gt.mean()), float(to_pred.mean())
    precision = float(np.mean(to_gt < threshold))
    recall = float(np.mean(to_pred < threshold))
    fscore = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    return 0.5 * (accuracy + completeness), fscore


def evaluate_pair(pred: trimesh.Trimesh, gt: trimesh.Trimesh, seed: int = 0) -> dict[str, float]:
    """The paper's metrics for one prediction: ``iou``, ``chamfer_l1``, ``fscore`` (0..1), and
    ``chamfer_l1_icp``, ``fscore_icp``: the point metrics after the IoU's ICP alignment."""
    iou, transform = aligned_voxel_iou(pred, gt)
    chamfer, fscore = chamfer_f(pred, gt, seed=seed)
    chamfer_icp, fscore_icp = chamfer_f(pred, gt, seed=seed, pred_transform=transform)
    return {"iou": iou, "chamfer_l1": chamfer, "fscore": fscore, "chamfer_l1_icp": chamfer_icp, "fscore_icp": fscore_icp}


# --------------------------------------------------------------------------- pictures

#: Side of each view of :func:`comparison_sheet` (pixels): the point metrics' frame spans
#: POINT_SCALE units in SHEET_VIEW * 0.9 pixels, so the F threshold (0.1) is about 3 pixels.
SHEET_VIEW = 320
#: The three views of :func:`comparison_sheet`: (label, axis drawn rightwards, axis drawn upwards).
SHEET_VIEWS = (("as photographed (x, y)", 0, 1), ("from the side (z, y)", 2, 1), ("from above (x, z)", 0, 2))
TRUTH_COLOUR = (70, 130, 255)
PREDICTION_COLOUR = (255, 140, 0)


def comparison_sheet(pred: trimesh.Trimesh, gt: trimesh.Trimesh, metrics: dict[str, float], n_points: int = 20_000) -> np.ndarray:
    """RGB picture of one prediction against its truth in the strict point metrics' frame.

    Each mesh is centred on its own bounding box with its longest edge POINT_SCALE long (what
    Chamfer-L1 and F compare), sampled, and drawn from three sides: the truth blue, the
    prediction orange, where both lie white. A wing plane at the wrong height against the
    box centre, or a part the template lacks, shows at a glance; the numbers cannot say where.
    """
    clouds = [_surface_points(_scaled(mesh, POINT_SCALE), n_points, seed=0) for mesh in (gt, pred)]
    pixels_per_unit = 0.9 * SHEET_VIEW / POINT_SCALE
    panels = []
    for label, right, up in SHEET_VIEWS:
        drawn = []
        for points in clouds:
            hit = np.zeros((SHEET_VIEW, SHEET_VIEW), bool)
            cols = np.clip(np.round(SHEET_VIEW / 2 + points[:, right] * pixels_per_unit), 0, SHEET_VIEW - 1).astype(int)
            rows = np.clip(np.round(SHEET_VIEW / 2 - points[:, up] * pixels_per_unit), 0, SHEET_VIEW - 1).astype(int)
            hit[rows, cols] = True
            drawn.append(hit)
        truth, prediction = drawn
        panel = np.zeros((SHEET_VIEW, SHEET_VIEW, 3), np.uint8)
        panel[truth] = TRUTH_COLOUR
        panel[prediction] = PREDICTION_COLOUR
        panel[truth & prediction] = 255
        cv2.putText(panel, label, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (220, 220, 220), 1, cv2.LINE_AA)
        panels.append(panel)
    sheet = np.concatenate(panels, axis=1)
    caption = "truth blue, reconstruction orange  " + "  ".join(f"{key} {metrics[key]:.3f}" for key in METRIC_KEYS if key in metrics)
    cv2.putText(sheet, caption, (6, SHEET_VIEW - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (220, 220, 220), 1, cv2.LINE_AA)
    return sheet


# --------------------------------------------------------------------------- drivers

#: Side of the square frontal render made when no renders are given (pixels).
RENDER_RESOLUTION = 512
#: Fraction of the frame the longest image-plane extent spans (as the shared renders).
RENDER_FILL = 0.9
METRIC_KEYS = ("iou", "chamfer_l1", "fscore")
#: The point metrics after the IoU's ICP (see the module docstring): written, not plotted.
ICP_METRIC_KEYS = ("chamfer_l1_icp", "fscore_icp")
CSV_FIELDS = ("id", "family", "subtype", *METRIC_KEYS, *ICP_METRIC_KEYS, "seconds", "error")


def render_frontal(mesh: trimesh.Trimesh, resolution: int = RENDER_RESOLUTION) -> tuple[np.ndarray, np.ndarray, dict]:
    """Orthographic render along -Z: (RGB uint8 image, bool mask, camera dict).

    Same camera as the shared renders: centred at the bbox centre, longest X/Y extent =
    90 % of the frame, one ray per pixel centre, Lambert shading (``frontal3d.photo_render``).
    """
    _check_mesh(mesh, "ground-truth")
    camera = frontal_camera(mesh, resolution, RENDER_FILL)
    rgba = photo_render_frontal(mesh, camera)
    return np.ascontiguousarray(rgba[..., :3]), rgba[..., 3] > 0, camera


def load_render(renders_dir: Path, mesh_id: str) -> tuple[np.ndarray, np.ndarray, dict]:
    """A given frontal render: its image, mask and camera (the shared data's layout)."""
    image = cv2.imread(str(renders_dir / f"{mesh_id}.png"), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(renders_dir / f"{mesh_id}_mask.png"), cv2.IMREAD_GRAYSCALE)
    camera_path = renders_dir / f"{mesh_id}.json"
    if image is None or mask is None or not camera_path.is_file():
        raise InputError(f"render of {mesh_id} missing in {renders_dir} (need .png, _mask.png and .json)")
    return image[..., ::-1].copy(), mask > 127, json.loads(camera_path.read_text())


def every_nth(items: list, every: int = 1, offset: int = 0) -> list:
    """Every ``every``-th of ``items`` from ``offset``: the halves (or thirds) a benchmark tunes
    on and reports on (``--every`` and ``--offset``)."""
    if every < 1 or not 0 <= offset < every:
        raise ConfigError("--every must be at least 1 and --offset in 0 .. every-1")
    return items[offset::every]


def load_mesh(path: Path) -> trimesh.Trimesh:
    """A ground-truth mesh as one triangle soup; an empty one is an input error."""
    mesh = trimesh.load(path, force="mesh")
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError(f"ground-truth mesh {path} has no triangles")
    return mesh


def run_evaluation(
    family: str,
    meshes_dir: Path,
    renders_dir: Path | None,
    reconstruct: Reconstruct,
    out_dir: Path,
    limit: int | None = None,
    progress: bool = True,
    sheets: bool = False,
) -> list[dict]:
    """Reconstruct every ``*.glb`` of ``meshes_dir`` from its frontal view and score it.

    The view is ``renders_dir/<id>.png``, ``<id>_mask.png``, ``<id>.json`` when given,
    otherwise rendered here by :func:`render_frontal`. Contract for ``reconstruct(image
    RGB uint8, mask bool, camera dict)``: it returns a mesh whose X/Y line up with the
    camera (``center``, ``half_width``: the ground truth's units and frame); its Z
    placement and overall scale are free, since every metric re-centres and normalizes
    each mesh. It may name the subtype it chose in ``mesh.metadata['subtype']``.
    A reconstruction that raises is recorded as a row with its error, not a crash.
    Writes ``metrics.csv``, ``summary.csv`` and ``boxplots.png`` into ``out_dir``, and with
    ``sheets`` each mesh's :func:`comparison_sheet` as ``sheets/<id>.png``.
    """
    meshes_dir, out_dir = Path(meshes_dir), Path(out_dir)
    paths = sorted(meshes_dir.glob("*.glb"))[:limit]
    if not paths:
        raise InputError(f"no *.glb meshes in {meshes_dir}")
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    bar = counter(len(paths), "mesh", f"evaluate {family}", progress)
    for path in paths:
        row = {"id": path.stem, "family": family, "subtype": "", "seconds": float("nan"), "error": ""}
        row.update({key: float("nan") for key in METRIC_KEYS + ICP_METRIC_KEYS})
        try:
            gt = load_mesh(path)
            image, mask, camera = load_render(Path(renders_dir), path.stem) if renders_dir else render_frontal(gt)
            start = time.perf_counter()
            prediction = reconstruct(image, mask, camera)
            row["seconds"] = time.perf_counter() - start
            row["subtype"] = str(prediction.metadata.get("subtype", ""))
            row.update(evaluate_pair(prediction, gt))
            if sheets:
                (out_dir / "sheets").mkdir(exist_ok=True)
                cv2.imwrite(str(out_dir / "sheets" / f"{path.stem}.png"), comparison_sheet(prediction, gt, row)[..., ::-1])
        except Exception as error:  # noqa: BLE001 - one bad mesh must not stop a benchmark
            row["error"] = f"{type(error).__name__}: {error}".splitlines()[0]
            if progress and not isinstance(error, InputError):
                traceback.print_exc()
        rows.append(row)
        bar.update(1)
    bar.close()
    write_csv(out_dir / "metrics.csv", CSV_FIELDS, rows)
    _write_summary(out_dir / "summary.csv", rows)
    _write_boxplots(out_dir / "boxplots.png", rows)
    return rows


def write_csv(path: Path, fields: tuple[str, ...], rows: list[dict]) -> None:
    """Rows as CSV with these columns (other keys are left out)."""
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


def _groups(rows: list[dict]) -> dict[tuple[str, str], list[dict]]:
    """Rows per (family, 'all') and per (family, subtype) when subtypes are known."""
    groups: dict[tuple[str, str], list[dict]] = {}
    for row in rows:
        groups.setdefault((row["family"], "all"), []).append(row)
        if row["subtype"]:
            groups.setdefault((row["family"], row["subtype"]), []).append(row)
    return groups


def _write_summary(path: Path, rows: list[dict]) -> None:
    """Mean and median of each metric per family and subtype, over the meshes that scored."""
    keys = METRIC_KEYS + ICP_METRIC_KEYS
    fields = ["family", "subtype", "n", "n_failed"] + [f"{k}_{s}" for k in keys for s in ("mean", "median")]
    summary = []
    for (family, subtype), members in _groups(rows).items():
        scored = [r for r in members if not r["error"]]
        line = {"family": family, "subtype": subtype, "n": len(scored), "n_failed": len(members) - len(scored)}
        for key in keys:
            values = [r[key] for r in scored]
            line[f"{key}_mean"] = statistics.fmean(values) if values else float("nan")
            line[f"{key}_median"] = statistics.median(values) if values else float("nan")
        summary.append(line)
    write_csv(path, tuple(fields), summary)


def _write_boxplots(path: Path, rows: list[dict]) -> None:
    """One box plot per metric, one box per family/subtype group (the paper's Fig. 13)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = _groups(rows)
    labels = [f"{family}\n{subtype}" for family, subtype in groups]
    titles = {"iou": "IoU", "chamfer_l1": "Chamfer-L1", "fscore": "F-score"}
    figure, axes = plt.subplots(1, 3, figsize=(4 + 1.5 * len(labels), 4))
    for axis, key in zip(axes, METRIC_KEYS):
        data = [[r[key] for r in members if not r["error"]] or [float("nan")] for members in groups.values()]
        axis.boxplot(data, tick_labels=labels)
        axis.set_title(titles[key])
        axis.grid(axis="y", alpha=0.3)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


# --------------------------------------------------------------------------- CLI glue
def pipeline_reconstructor(plugins, family: str, **settings) -> Reconstruct:
    """The frontal3d pipeline as a ``reconstruct`` callable, the mask given (the paper's protocol)."""
    from frontal3d.pipeline import reconstruct

    def run(image: np.ndarray, mask: np.ndarray, camera: dict) -> trimesh.Trimesh:
        result = reconstruct(image, family, mask=mask, plugins=plugins, **settings)
        mesh = result.mesh.copy()
        mesh.metadata["subtype"] = result.report["subtype"]
        return mesh

    return run


def summary_lines(rows: list[dict]) -> list[str]:
    """The summary table as text lines (mean / median per family and subtype)."""
    lines = [f"{'group':<22}{'n':>4}{'failed':>8}{'IoU':>14}{'Chamfer-L1':>16}{'F-score':>14}{'CD after ICP':>16}{'F after ICP':>14}"]
    for (family, subtype), members in _groups(rows).items():
        scored = [r for r in members if not r["error"]]
        cells = []
        for key in METRIC_KEYS + ICP_METRIC_KEYS:
            values = [r[key] for r in scored]
            cells.append(f"{statistics.fmean(values):.3f}/{statistics.median(values):.3f}" if values else "-")
        widths = (14, 16, 14, 16, 14)
        lines.append(f"{family + '/' + subtype:<22}{len(scored):>4}{len(members) - len(scored):>8}" + "".join(f"{c:>{w}}" for c, w in zip(cells, widths)))
    lines.append("(mean/median; F-score as a fraction; the last two: point metrics after the IoU's ICP alignment)")
    return lines
