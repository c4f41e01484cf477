"""Frontal-gate benchmark: how often does the classifier chain accept turned views?

Each ground-truth mesh (canonical frame) is turned about image-up ("yaw") and
image-right ("pitch") by each angle, both ways, and rendered in its own colours as a
shaded frontal image (:func:`frontal3d.evaluate.render_frontal`, the shared renders' shading). The
pipeline's classifier chain then judges the image with the true silhouette given as
the mask, so the figures measure the gate alone, not the segmenter. Views within
``FRONTAL_LIMIT_DEG`` should be accepted, views turned ``TURNED_FROM_DEG`` or more
rejected; in between (10-30°) nothing is expected and nothing is scored.

:func:`evaluate_gate_on_synth` judges ``frontal3d synth`` samples the same way, by their
frontal / turned labels: the held-out synthetic figures the gate's margins are chosen on.

Both also score the subtype the chain picks on the frontal views it accepts: synthetic
samples by their own labels, meshes by a labels file (``id,family,subtype``; the shared
meshes' hand labels ship as ``docs/shared_subtypes.csv``).
"""

from __future__ import annotations

import csv
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import trimesh

from frontal3d.errors import InputError, NotFrontalError
from frontal3d.evaluate import load_render, render_frontal, write_csv
from frontal3d.family import Family
from frontal3d.photo_render import load_coloured_mesh
from frontal3d.pipeline import run_classifiers
from frontal3d.plugins import Plugins
from frontal3d.synth import read_labels_of, read_sample

#: Turns (degrees) that still count as the canonical view (the paper's ±10°).
FRONTAL_LIMIT_DEG = 10.0
#: Turns (degrees) from which on a view must be rejected (the issue's target).
TURNED_FROM_DEG = 30.0
DEFAULT_ANGLES = (0.0, 10.0, 30.0, 45.0, 60.0, 90.0)
#: Side of the rendered square views (the classifiers compare masks at 128 px).
DEFAULT_RESOLUTION = 256
CSV_FIELDS = ("id", "axis", "degrees", "accepted", "label", "confidence", "subtype", "true_subtype", "seconds", "reason")
#: How the summary names the turns about each axis.
AXIS_NAMES = {"yaw": "about image-up (yaw)", "pitch": "about image-right (pitch)"}
#: Synthetic samples add their label (1 = frontal) and judge turns by the larger of yaw and pitch.
SYNTH_CSV_FIELDS = CSV_FIELDS + ("frontal",)


@dataclass(frozen=True)
class GateSummary:
    """Acceptance per turn and the balanced accuracies the issue asks for."""

    accept_rate: dict[float, float]  # by |degrees|
    count: dict[float, int]
    balanced_0: float  # 0° (accept) vs >= 30° (reject)
    balanced_10: float  # 0° and ±10° vs >= 30°
    #: 0° vs >= 30° turns about one axis only ("yaw": image-up, the issue's target; "pitch": image-right).
    balanced_by_axis: dict[str, float] = field(default_factory=dict)
    renders_accepted: tuple[int, int] | None = None  # (accepted, scored) of the given frontal renders
    subtype_right: tuple[int, int] | None = None  # (right, scored) over accepted, labelled frontal views

    def lines(self) -> list[str]:
        out = [f"{degrees:>4.0f}°: accepted {self.accept_rate[degrees]:.3f} of {self.count[degrees]}"
               for degrees in sorted(self.accept_rate)]
        if self.renders_accepted:
            accepted, scored = self.renders_accepted
            out.append(f"given frontal renders: accepted {accepted / scored:.3f} of {scored}")
        out.append(f"balanced accuracy 0° vs >= {TURNED_FROM_DEG:.0f}°: {self.balanced_0:.3f}")
        if not np.isnan(self.balanced_10):
            out.append(f"balanced accuracy 0-{FRONTAL_LIMIT_DEG:.0f}° vs >= {TURNED_FROM_DEG:.0f}°: {self.balanced_10:.3f}")
        for axis, value in self.balanced_by_axis.items():
            out.append(f"balanced accuracy 0° vs >= {TURNED_FROM_DEG:.0f}° {AXIS_NAMES[axis]} only: {value:.3f}")
        out.extend(_subtype_lines(self.subtype_right))
        return out


def turned(mesh: trimesh.Trimesh, axis: str, degrees: float) -> trimesh.Trimesh:
    """A copy of ``mesh`` turned about its bounding-box centre: ``yaw`` about +Y (image-up), ``pitch`` about +X (image-right)."""
    direction = [0.0, 1.0, 0.0] if axis == "yaw" else [1.0, 0.0, 0.0]
    rotation = trimesh.transformations.rotation_matrix(np.deg2rad(degrees), direction, mesh.bounds.mean(axis=0))
    copy = mesh.copy()
    copy.apply_transform(rotation)
    return copy


def views(angles: Iterable[float]) -> list[tuple[str, float]]:
    """(axis, signed degrees) to render: the canonical view once, every other angle both ways about both axes."""
    out = []
    for degrees in sorted({abs(float(a)) for a in angles}):
        if degrees == 0:
            out.append(("yaw", 0.0))
            continue
        out.extend((axis, sign * degrees) for axis in ("yaw", "pitch") for sign in (1.0, -1.0))
    return out


def evaluate_gate(plugins: Plugins, family: str, meshes_dir: Path, out_dir: Path | None = None,
                  angles: Iterable[float] = DEFAULT_ANGLES, resolution: int = DEFAULT_RESOLUTION,
                  limit: int | None = None, settings: dict | None = None, renders_dir: Path | None = None,
                  subtype: str | None = None, progress: Callable[[int], None] | None = None,
                  labels: dict[str, str] | None = None, sheet: bool = False) -> tuple[list[dict], GateSummary]:
    """Judge every ``*.glb`` of ``meshes_dir`` turned by each angle; writes ``gate.csv`` into ``out_dir`` when given.

    With ``renders_dir`` (``<id>.png``, ``<id>_mask.png``, ``<id>.json``, as in the shared data), each
    mesh's given frontal render is judged too (axis ``render`` in the rows, counted
    apart from the rendered turns): the cost of a stricter gate on other renderings.
    ``subtype`` judges against that subtype's template only (as ``reconstruct --subtype``).
    ``labels`` (mesh id -> true subtype, :func:`read_subtype_labels`) scores the subtype
    picked on the accepted 0° views and given renders. With ``sheet`` (and ``out_dir``), the
    views judged the wrong way are pictured in ``misjudged.png`` (:func:`misjudged_sheet`).
    """
    fam = plugins.family(family)
    paths = sorted(Path(meshes_dir).glob("*.glb"))[:limit]
    if not paths:
        raise InputError(f"no *.glb meshes in {meshes_dir}")
    fam_settings = plugins.settings(fam.name, settings or {})
    labels = labels or {}
    rows, wrong_views = [], []

    def judge(image: np.ndarray, mask: np.ndarray, view: dict) -> None:
        row = _judged(plugins, fam, fam_settings, subtype, image, mask) | view
        rows.append(row)
        if sheet and misjudged(row):
            wrong_views.append((image, row))

    for path in paths:
        mesh = load_coloured_mesh(path)
        for axis, degrees in views(angles):
            image, mask, _ = render_frontal(turned(mesh, axis, degrees), resolution)
            true_subtype = labels.get(path.stem, "") if degrees == 0 else ""
            judge(image, mask, {"id": path.stem, "axis": axis, "degrees": degrees, "true_subtype": true_subtype})
        if renders_dir is not None:
            image, mask, _ = load_render(Path(renders_dir), path.stem)
            judge(image, mask, {"id": path.stem, "axis": "render", "degrees": 0.0, "true_subtype": labels.get(path.stem, "")})
        if progress:
            progress(1)
    summary = summarize(rows)
    if out_dir is not None:
        _write(Path(out_dir), rows, CSV_FIELDS, summary.lines())
        if sheet:
            cv2.imwrite(str(Path(out_dir) / "misjudged.png"), misjudged_sheet(wrong_views)[..., ::-1])
    return rows, summary


def misjudged(row: dict) -> bool:
    """Whether the gate judged this view the wrong way: a view within FRONTAL_LIMIT_DEG (or a given
    render) turned down, or one turned TURNED_FROM_DEG or more accepted. Views in between never are."""
    turn = abs(float(row["degrees"]))
    if row["axis"] == "render" or turn <= FRONTAL_LIMIT_DEG:
        return not row["accepted"]
    return bool(row["accepted"]) and turn >= TURNED_FROM_DEG


#: Thumbnail side and thumbnails per row of :func:`misjudged_sheet`.
SHEET_THUMB = 192
SHEET_COLUMNS = 6


def misjudged_sheet(views: list[tuple[np.ndarray, dict]]) -> np.ndarray:
    """RGB contact sheet of the views the gate judged the wrong way, each captioned with the
    mesh, the turn and the verdict (a turned view accepted, with its agreement; a front view
    turned down): which shapes fool the gate, at a glance. A one-line note when there are none."""
    if not views:
        blank = np.full((40, 4 * SHEET_THUMB, 3), 255, np.uint8)
        cv2.putText(blank, "no view judged the wrong way", (8, 26), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1, cv2.LINE_AA)
        return blank
    tiles = []
    for image, row in views:
        tile = np.full((SHEET_THUMB + 36, SHEET_THUMB, 3), 255, np.uint8)
        tile[:SHEET_THUMB] = cv2.resize(np.ascontiguousarray(image[..., :3]), (SHEET_THUMB, SHEET_THUMB), interpolation=cv2.INTER_AREA)
        verdict = f"accepted {row['confidence']}" if row["accepted"] else "turned down"
        turn = "render" if row["axis"] == "render" else f"{row['axis']} {float(row['degrees']):+.0f}"
        for line, text in enumerate((str(row["id"])[:28], f"{turn}: {verdict}")):
            cv2.putText(tile, text, (4, SHEET_THUMB + 14 + 16 * line), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        tiles.append(tile)
    tiles += [np.full_like(tiles[0], 255)] * (-len(tiles) % SHEET_COLUMNS)
    return np.concatenate([np.concatenate(tiles[k : k + SHEET_COLUMNS], axis=1) for k in range(0, len(tiles), SHEET_COLUMNS)], axis=0)


@dataclass(frozen=True)
class SynthGateSummary:
    """Accept rate of the frontal-labelled samples, reject rate of the turned ones, their mean."""

    frontal_accepted: float
    frontal_count: int
    turned_rejected: float
    turned_count: int
    subtype_right: tuple[int, int] | None = None  # (right, scored) over accepted frontal samples

    @property
    def balanced(self) -> float:
        return 0.5 * (self.frontal_accepted + self.turned_rejected)

    def lines(self) -> list[str]:
        return [f"frontal samples (within ±{FRONTAL_LIMIT_DEG:.0f}°): accepted {self.frontal_accepted:.3f} of {self.frontal_count}",
                f"turned samples: rejected {self.turned_rejected:.3f} of {self.turned_count}",
                f"balanced accuracy: {self.balanced:.3f}"] + _subtype_lines(self.subtype_right)


def evaluate_gate_on_synth(plugins: Plugins, family: str, data_dir: Path, out_dir: Path | None = None,
                           limit: int | None = None, settings: dict | None = None, subtype: str | None = None,
                           progress: Callable[[int], None] | None = None) -> tuple[list[dict], SynthGateSummary]:
    """Judge the first ``limit`` samples of a ``frontal3d synth`` folder with their true masks;
    writes ``gate.csv`` and ``summary.txt`` into ``out_dir`` when given."""
    data_dir = Path(data_dir)
    labels = read_labels_of(data_dir, family)
    fam = plugins.family(family)
    fam_settings = plugins.settings(fam.name, settings or {})
    rows = []
    for label in labels[:limit]:
        image, mask = read_sample(data_dir, label["file"])
        turn = max(abs(float(label["yaw"])), abs(float(label["pitch"])))
        rows.append(_judged(plugins, fam, fam_settings, subtype, image, mask)
                    | {"id": label["file"], "axis": "synth", "degrees": turn, "frontal": int(label["frontal"]),
                       "true_subtype": label["subtype"] if int(label["frontal"]) else ""})
        if progress:
            progress(1)
    frontal = [int(row["accepted"]) for row in rows if row["frontal"]]
    turned = [1 - int(row["accepted"]) for row in rows if not row["frontal"]]
    if not frontal or not turned:
        raise InputError(f"{data_dir}: the gate needs both frontal and turned samples (found {len(frontal)} and {len(turned)})")
    summary = SynthGateSummary(float(np.mean(frontal)), len(frontal), float(np.mean(turned)), len(turned), subtype_score(rows))
    if out_dir is not None:
        _write(Path(out_dir), rows, SYNTH_CSV_FIELDS, summary.lines())
    return rows, summary


def _write(out_dir: Path, rows: list[dict], fields: tuple[str, ...], lines: list[str]) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    write_csv(out_dir / "gate.csv", fields, rows)
    (out_dir / "summary.txt").write_text("\n".join(lines) + "\n")


def _judged(plugins: Plugins, fam: Family, settings: dict, subtype: str | None, image: np.ndarray, mask: np.ndarray) -> dict:
    """The classifier chain's verdict on one view, as a CSV row (without the view's name)."""
    start = time.perf_counter()
    try:
        decisions, picked = run_classifiers(plugins, image, mask, fam, settings, subtype)[:2]
        gate = next((d for d in decisions if d.name == "frontal"), decisions[0])
        row = {"accepted": 1, "label": gate.label, "confidence": round(gate.confidence, 4), "reason": gate.reason, "subtype": picked}
    except NotFrontalError as rejection:
        row = {"accepted": 0, "label": "not frontal", "confidence": "", "reason": str(rejection), "subtype": ""}
    return row | {"seconds": round(time.perf_counter() - start, 3)}


def summarize(rows: list[dict]) -> GateSummary:
    """Acceptance per |turn|; balanced accuracy = mean of the frontal accept rate and the turned reject rate."""
    subtype_right = subtype_score(rows)
    given = [int(row["accepted"]) for row in rows if row.get("axis") == "render"]
    rows = [row for row in rows if row.get("axis") != "render"]
    by_turn: dict[float, list[int]] = {}
    for row in rows:
        by_turn.setdefault(abs(float(row["degrees"])), []).append(int(row["accepted"]))
    rate = {degrees: float(np.mean(values)) for degrees, values in by_turn.items()}
    turned_rows = [v for d, values in by_turn.items() if d >= TURNED_FROM_DEG for v in values]
    frontal_0 = by_turn.get(0.0, [])
    frontal_10 = [v for d, values in by_turn.items() if d <= FRONTAL_LIMIT_DEG for v in values]

    def balanced(frontal: list[int], turned: list[int]) -> float:
        if not frontal or not turned:
            return float("nan")
        return 0.5 * (float(np.mean(frontal)) + 1.0 - float(np.mean(turned)))

    turned_by_axis = {axis: [int(row["accepted"]) for row in rows
                             if row.get("axis") == axis and abs(float(row["degrees"])) >= TURNED_FROM_DEG] for axis in AXIS_NAMES}
    has_10 = any(0 < d <= FRONTAL_LIMIT_DEG for d in by_turn)
    return GateSummary(accept_rate=rate, count={d: len(v) for d, v in by_turn.items()},
                       balanced_0=balanced(frontal_0, turned_rows),
                       balanced_10=balanced(frontal_10, turned_rows) if has_10 else float("nan"),
                       balanced_by_axis={axis: balanced(frontal_0, turned) for axis, turned in turned_by_axis.items() if turned},
                       renders_accepted=(sum(given), len(given)) if given else None, subtype_right=subtype_right)


def subtype_score(rows: list[dict]) -> tuple[int, int] | None:
    """(right, scored) subtype picks over the accepted rows that carry a true subtype; None if none do.

    Rejected views are left out: the chain picks no subtype for them, and the gate's
    figures already count them."""
    scored = [row for row in rows if row.get("true_subtype") and int(row["accepted"])]
    if not scored:
        return None
    return sum(row["subtype"] == row["true_subtype"] for row in scored), len(scored)


def _subtype_lines(right: tuple[int, int] | None) -> list[str]:
    if right is None:
        return []
    hits, scored = right
    return [f"subtype right on accepted frontal views: {hits / scored:.3f} of {scored}"]


def read_subtype_labels(path: Path, family: Family) -> dict[str, str]:
    """Mesh id -> true subtype of ``family`` from a CSV with columns id, family, subtype.

    Rows of other families, and rows with an empty subtype (no fair label), are skipped; a
    subtype the family does not have is refused, as a typo would silently score 0.
    """
    path = Path(path)
    try:
        with path.open(newline="") as handle:
            rows = list(csv.DictReader(handle))
    except OSError as error:
        raise InputError(f"cannot read subtype labels {path}: {error.strerror}") from None
    if rows and not {"id", "family", "subtype"} <= set(rows[0]):
        raise InputError(f"{path}: expected the columns id, family, subtype")
    labels = {row["id"]: row["subtype"] for row in rows if row["family"] == family.name and row["subtype"]}
    unknown = sorted(set(labels.values()) - set(family.subtypes))
    if unknown:
        raise InputError(f"{path}: {', '.join(unknown)} is not a subtype of {family.name} ({', '.join(family.subtypes)})")
    return labels
