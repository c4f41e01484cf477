"""Gate benchmark: a generated car turned away from its side view is scored as it should be."""

from __future__ import annotations

import csv
import json

import cv2
import numpy as np
import pytest
import trimesh

from frontal3d.cli import main
from frontal3d.errors import InputError
from frontal3d.eval_gate import (SHEET_COLUMNS, SHEET_THUMB, evaluate_gate, misjudged, misjudged_sheet, read_subtype_labels, subtype_score,
                                 summarize, views)
from frontal3d.evaluate import render_frontal
from frontal3d.plugins import Plugins
from shapes import box_car


def _box_car() -> trimesh.Trimesh:
    """The shared box car at unit size, as the ground-truth meshes are."""
    car = box_car()
    car.apply_scale(1.0 / max(car.extents))
    return car


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("meshes")
    _box_car().export(folder / "boxcar.glb")
    return folder


def test_views_cover_both_axes_and_signs():
    assert views([0, 30]) == [("yaw", 0.0), ("yaw", 30.0), ("yaw", -30.0), ("pitch", 30.0), ("pitch", -30.0)]


def test_side_view_accepted_and_end_on_views_rejected_with_reasons(meshes, tmp_path):
    renders = tmp_path / "renders"
    renders.mkdir()
    image, mask, camera = render_frontal(_box_car(), 200)
    (renders / "boxcar.json").write_text(json.dumps(camera))
    cv2.imwrite(str(renders / "boxcar.png"), image[..., ::-1])
    cv2.imwrite(str(renders / "boxcar_mask.png"), mask.astype("uint8") * 255)
    rows, summary = evaluate_gate(Plugins(), "car", meshes, tmp_path, angles=(0, 90), resolution=160,
                                  renders_dir=renders, subtype="sedan", labels={"boxcar": "suv"})
    by_view = {(r["axis"], r["degrees"]): r for r in rows}
    assert by_view[("yaw", 0.0)]["accepted"] == 1
    assert all(by_view[(axis, sign * 90.0)]["accepted"] == 0 for axis in ("yaw", "pitch") for sign in (1, -1))
    assert all("side view" in by_view[(axis, 90.0)]["reason"] for axis in ("yaw", "pitch"))
    assert summary.balanced_0 == 1.0
    assert summary.renders_accepted == (1, 1)
    # Judged against the sedan only, the box car labelled SUV is a wrong pick on both frontal views.
    assert summary.subtype_right == (0, 2)
    assert any(line.startswith("subtype right on accepted frontal views: 0.000 of 2") for line in summary.lines())
    with (tmp_path / "gate.csv").open() as handle:
        written = list(csv.DictReader(handle))
    assert len(written) == 6
    assert {row["true_subtype"] for row in written if row["degrees"] == "0.0"} == {"suv"}
    assert {row["true_subtype"] for row in written if row["degrees"] != "0.0"} == {""}


def test_misjudged_views_are_front_views_turned_down_and_turned_views_accepted():
    def row(axis: str, degrees: float, accepted: int) -> dict:
        return {"id": "m", "axis": axis, "degrees": degrees, "accepted": accepted, "confidence": 0.5}

    assert misjudged(row("render", 0.0, 0)) and misjudged(row("yaw", -10.0, 0)) and misjudged(row("pitch", 30.0, 1))
    assert not misjudged(row("yaw", 0.0, 1)) and not misjudged(row("yaw", 45.0, 0))
    assert not misjudged(row("yaw", 20.0, 1)) and not misjudged(row("yaw", 20.0, 0))  # between the two: nothing expected
    image = np.zeros((100, 100, 3), np.uint8)
    sheet = misjudged_sheet([(image, row("yaw", 30.0, 1))] * (SHEET_COLUMNS + 1))
    assert sheet.shape[1] == SHEET_COLUMNS * SHEET_THUMB and sheet.shape[0] == 2 * (SHEET_THUMB + 36)  # two rows, the last padded
    assert misjudged_sheet([]).shape[0] < SHEET_THUMB  # a one-line note


def test_verbose_gate_run_pictures_its_misjudged_views(meshes, tmp_path):
    # The sheet holds exactly the views gate.csv shows judged the wrong way (a note when there are none).
    assert main(["evaluate-gate", "--family", "car", "--meshes", str(meshes), "--angles", "0,90", "--resolution", "128",
                 "-o", str(tmp_path), "-v"]) == 0
    sheet = cv2.imread(str(tmp_path / "misjudged.png"))
    with (tmp_path / "gate.csv").open() as handle:
        wrong = [r for r in csv.DictReader(handle) if misjudged({**r, "accepted": int(r["accepted"])})]
    rows = -(-len(wrong) // SHEET_COLUMNS)
    assert sheet.shape[0] == (rows * (SHEET_THUMB + 36) if wrong else misjudged_sheet([]).shape[0])


def test_subtype_score_counts_accepted_labelled_views_only():
    rows = [{"accepted": 1, "subtype": "sedan", "true_subtype": "sedan"},
            {"accepted": 1, "subtype": "suv", "true_subtype": "sports"},
            {"accepted": 0, "subtype": "", "true_subtype": "sedan"},
            {"accepted": 1, "subtype": "suv", "true_subtype": ""}]
    assert subtype_score(rows) == (1, 2)
    assert subtype_score(rows[2:]) is None


def test_subtype_labels_file_keeps_its_family_and_refuses_unknown_subtypes(tmp_path):
    labels = tmp_path / "labels.csv"
    labels.write_text("id,family,subtype\na,car,sedan\nb,airplane,fighter\nc,car,\n")
    car = Plugins().family("car")
    assert read_subtype_labels(labels, car) == {"a": "sedan"}
    labels.write_text("id,family,subtype\na,car,limousine\n")
    with pytest.raises(InputError, match="limousine is not a subtype of car"):
        read_subtype_labels(labels, car)
    with pytest.raises(InputError, match="cannot read subtype labels"):
        read_subtype_labels(tmp_path / "missing.csv", car)


def test_summary_balances_frontal_acceptance_against_turned_rejection():
    rows = [{"axis": "yaw", "degrees": 0.0, "accepted": 1}, {"axis": "yaw", "degrees": 10.0, "accepted": 0},
            {"axis": "pitch", "degrees": 30.0, "accepted": 1}, {"axis": "yaw", "degrees": -45.0, "accepted": 0},
            {"axis": "yaw", "degrees": 45.0, "accepted": 0}, {"axis": "pitch", "degrees": 20.0, "accepted": 1}]
    summary = summarize(rows)
    assert summary.accept_rate[45.0] == 0.0 and summary.count[45.0] == 2
    assert summary.balanced_0 == pytest.approx(0.5 * (1.0 + 2 / 3))
    assert summary.balanced_10 == pytest.approx(0.5 * (0.5 + 2 / 3))
    # The target judges turns about image-up: here both yaw turns are rejected, the pitched one is not.
    assert summary.balanced_by_axis == {"yaw": 1.0, "pitch": pytest.approx(0.5)}
    assert any("about image-up (yaw) only: 1.000" in line for line in summary.lines())


def test_cli_rejects_bad_angles(meshes, capsys):
    assert main(["evaluate-gate", "--family", "car", "--meshes", str(meshes), "--angles", "0,abc"]) == 2
    assert "--angles" in capsys.readouterr().err


def test_synth_mode_scores_samples_by_their_labels(tmp_path, capsys):
    data = tmp_path / "syn"
    assert main(["synth", "--family", "car", "-n", "8", "-o", str(data), "--seed", "5", "--resolution", "96"]) == 0
    assert main(["evaluate-gate", "--family", "car", "--synth", str(data), "-o", str(tmp_path / "gate")]) == 0
    printed = capsys.readouterr().out
    with (data / "labels.csv").open() as handle:
        labels = {row["file"]: int(row["frontal"]) for row in csv.DictReader(handle)}
    with (tmp_path / "gate" / "gate.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert {row["id"]: int(row["frontal"]) for row in rows} == labels
    frontal = sum(labels.values())
    assert f"accepted 1.000 of {frontal}\n" in printed and f"of {len(labels) - frontal}\n" in printed
    # The car's own template, perturbed and seen within ±10°, is a side view to the gate.
    assert all(row["accepted"] == "1" for row in rows if row["frontal"] == "1")
    # ... and the subtype picked on it is scored against the sample's own label.
    with (data / "labels.csv").open() as handle:
        truth = {row["file"]: row["subtype"] for row in csv.DictReader(handle) if row["frontal"] == "1"}
    right = sum(row["subtype"] == truth[row["id"]] for row in rows if row["id"] in truth)
    assert f"subtype right on accepted frontal views: {right / frontal:.3f} of {frontal}\n" in printed


def test_synth_mode_refuses_another_familys_samples(tmp_path, capsys):
    data = tmp_path / "syn"
    assert main(["synth", "--family", "car", "-n", "2", "-o", str(data), "--resolution", "64"]) == 0
    assert main(["evaluate-gate", "--family", "guitar", "--synth", str(data), "-o", str(tmp_path / "gate")]) != 0
    assert "holds car samples, not guitar" in capsys.readouterr().err
