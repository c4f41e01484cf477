"""The mask benchmark: backgrounds, compositing and the evaluate-masks command on drawn renders."""

from __future__ import annotations

import csv

import cv2
import numpy as np
import pytest

from frontal3d.cli import main
from frontal3d.eval_masks import BACKGROUNDS, composite_photo, make_background, mask_iou


def _write_renders(folder, count: int = 3, size: int = 160) -> None:
    """RGBA 'renders' of guitar-like shapes (body + neck) in saturated colours, alpha = silhouette."""
    folder.mkdir()
    colours = [(200, 40, 30), (30, 60, 170), (40, 140, 50)]
    for index in range(count):
        alpha = np.zeros((size, size), np.uint8)
        cv2.ellipse(alpha, (size // 2 + 4 * index, int(size * 0.68)), (size // 6, size // 5), 0, 0, 360, 255, -1)
        cv2.rectangle(alpha, (size // 2 - 5 + 4 * index, size // 8), (size // 2 + 5 + 4 * index, int(size * 0.6)), 255, -1)
        rgba = np.zeros((size, size, 4), np.uint8)
        rgba[alpha > 0, :3] = colours[index % len(colours)]
        rgba[..., 3] = alpha
        cv2.imwrite(str(folder / f"r{index}.png"), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
        cv2.imwrite(str(folder / f"r{index}_mask.png"), alpha)


def test_backgrounds_are_reproducible_and_as_documented():
    for kind in BACKGROUNDS:
        first = make_background(kind, 64, np.random.default_rng([5, 0]))
        assert first.shape == (64, 64, 3) and first.min() >= 0 and first.max() <= 255
        assert np.array_equal(first, make_background(kind, 64, np.random.default_rng([5, 0])))
        assert not np.array_equal(first, make_background(kind, 64, np.random.default_rng([6, 0])))
    assert np.ptp(make_background("plain", 64, np.random.default_rng(1)), axis=(0, 1)).max() == 0
    gradient = make_background("gradient", 64, np.random.default_rng(1))
    assert np.ptp(gradient, axis=(0, 1)).max() > 10  # it does vary
    # a gradient is smooth: neighbouring pixels differ far less than the ends
    assert np.abs(np.diff(gradient, axis=1)).max() < np.ptp(gradient, axis=(0, 1)).max() / 10


def test_composite_keeps_the_object_and_adds_sensor_noise():
    rgba = np.zeros((32, 32, 4), np.uint8)
    rgba[8:24, 8:24] = (200, 10, 10, 255)
    photo = composite_photo(rgba, "plain", np.random.default_rng(0))
    assert photo.shape == (32, 32, 3) and photo.dtype == np.uint8
    assert abs(photo[8:24, 8:24, 0].mean() - 200) < 2 and photo[8:24, 8:24].std() > 1


def test_mask_iou():
    a = np.zeros((4, 4), bool)
    b = a.copy()
    a[:2], b[1:3] = True, True
    assert mask_iou(a, b) == pytest.approx(4 / 12)
    assert mask_iou(a, a) == 1.0 and mask_iou(np.zeros_like(a), np.zeros_like(a)) == 1.0


def test_evaluate_masks_scores_every_render_over_each_background(tmp_path, capsys):
    renders = tmp_path / "renders"
    _write_renders(renders)
    out = tmp_path / "out"
    assert main(["evaluate-masks", "--family", "guitar", "--renders", str(renders), "--backgrounds", "plain,gradient", "--every", "2",
                 "--set", "weights={}", "-o", str(out), "-v"]) == 0  # the training-free chain alone
    with (out / "masks.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    # every second render (r0, r2) over two backgrounds
    assert sorted((r["render"], r["background"]) for r in rows) == [("r0", "gradient"), ("r0", "plain"), ("r2", "gradient"), ("r2", "plain")]
    assert all(float(r["iou"]) > 0.9 and r["segmenter"] == "GrabCut (training-free)" for r in rows)
    with (out / "summary.csv").open() as handle:
        summary = {r["background"]: r for r in csv.DictReader(handle)}
    assert set(summary) == {"plain", "gradient"} and summary["plain"]["images"] == "2"
    sheet = cv2.imread(str(out / "debug" / "r0_plain.png"))
    assert sheet is not None and sheet.shape[1] == 3 * sheet.shape[0]  # input | mask | truth
    assert "plain" in capsys.readouterr().out


def test_evaluate_masks_gives_one_line_errors(tmp_path, capsys):
    renders = tmp_path / "renders"
    _write_renders(renders, count=1)
    assert main(["evaluate-masks", "--family", "guitar", "--renders", str(renders), "--backgrounds", "plain,stripes", "-o", str(tmp_path / "o")]) != 0
    assert "unknown background 'stripes'" in capsys.readouterr().err
    assert main(["evaluate-masks", "--family", "guitar", "--renders", str(tmp_path / "empty"), "-o", str(tmp_path / "o")]) != 0
    assert "no <id>.png renders" in capsys.readouterr().err
    assert main(["evaluate-masks", "--family", "guitar", "--renders", str(renders), "--every", "2", "--offset", "2", "-o", str(tmp_path / "o")]) != 0
    assert "--offset in 0 .. every-1" in capsys.readouterr().err
