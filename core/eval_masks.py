"""Mask benchmark: the segmenter chain on RGBA renders composited over procedural backgrounds.

Each render ``<id>.png`` (RGBA, alpha = silhouette) is put over each background with
:func:`frontal3d.photo_render.composite`, Gaussian sensor noise (sigma :data:`SENSOR_NOISE`)
is added, and the opaque photo goes through the segmenter chain exactly as
``reconstruct`` runs it with no mask given (:func:`frontal3d.pipeline.segment_object`).
The score is the IoU of the chosen object's mask with the alpha channel (> 127).

Backgrounds (square, as large as the render, from ``numpy.random.default_rng([seed,
render index, background index])``, so a figure is reproducible and a render keeps its
backgrounds whatever ``every`` selects; colours from :func:`frontal3d.synth.random_colour`):

* ``plain``: one colour (dark one time in five).
* ``gradient``: a linear ramp between two colours in a random direction.
* ``noise``: one colour under fine value noise (cells of 1/48-1/128 of the side, ±25 %):
  paper, fabric, a grainy wall.
* ``mild``: a tinted gradient (the second colour the first scaled by 0.75-0.95 per
  channel), a 25 % vignette, low-contrast texture (±6 % value noise, 16-48 cells) and
  three faint soft shapes (20 % opacity).
* ``blobs``: a gradient with four to seven strong soft blobs of random colours, the hard case.
"""

from __future__ import annotations

import csv
import statistics
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Callable, Sequence

import cv2
import numpy as np

from frontal3d.errors import ConfigError, Frontal3DError, InputError
from frontal3d.evaluate import every_nth, write_csv
from frontal3d.imageio import read_image
from frontal3d.photo_render import composite
from frontal3d.pipeline import Report, segment_object
from frontal3d.plugins import Plugins
from frontal3d.synth import linear_gradient, random_colour, random_direction, random_gradient, smooth_noise, soft_blobs

BACKGROUNDS = ("plain", "gradient", "noise", "mild", "blobs")
#: Standard deviation of the sensor noise added to every composite (8-bit levels).
SENSOR_NOISE = 3.0
#: The issue's target mask IoU, counted per background in the summary.
TARGET_IOU = 0.95
#: Side of each panel of a debug sheet.
SHEET_PANEL = 256


@dataclass
class MaskScore:
    """One composite's result: its mask IoU (0 when the chain found nothing) and time."""

    family: str
    render: str
    background: str
    iou: float
    seconds: float
    segmenter: str
    error: str = ""


def make_background(kind: str, resolution: int, rng: np.random.Generator) -> np.ndarray:
    """A square float RGB background of one of :data:`BACKGROUNDS` (see the module docstring)."""
    if kind == "plain":
        return np.broadcast_to(random_colour(rng, rng.random() < 0.2), (resolution, resolution, 3)).copy()
    if kind == "gradient":
        return random_gradient(resolution, rng)
    if kind == "noise":
        texture = smooth_noise(resolution, rng, cells=rng.integers(48, 128))
        return np.clip(random_colour(rng, False) * (1 + 0.25 * texture[..., None]), 0, 255)
    if kind == "mild":
        start = random_colour(rng, False)
        background = linear_gradient(resolution, start, start * rng.uniform(0.75, 0.95, size=3), random_direction(rng))
        axis = np.linspace(-1, 1, resolution)
        radius2 = (axis[None, :] ** 2 + axis[:, None] ** 2) / 2
        background *= (1 - 0.25 * radius2)[..., None]
        background *= 1 + 0.06 * smooth_noise(resolution, rng, cells=rng.integers(16, 48))[..., None]
        return soft_blobs(background, rng, 3, opacity=0.2)
    if kind == "blobs":
        return soft_blobs(random_gradient(resolution, rng), rng, int(rng.integers(4, 8)))
    raise ConfigError(f"unknown background {kind!r} (choose from {', '.join(BACKGROUNDS)})")


def composite_photo(rgba: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
    """``rgba`` over a fresh ``kind`` background, with sensor noise: an opaque RGB uint8 photo."""
    height, width = rgba.shape[:2]
    background = make_background(kind, max(height, width), rng)[:height, :width]
    photo = composite(rgba, background).astype(np.float32) + rng.normal(0, SENSOR_NOISE, (height, width, 3))
    return np.clip(np.round(photo), 0, 255).astype(np.uint8)


def mask_iou(found: np.ndarray, truth: np.ndarray) -> float:
    """Intersection over union of two boolean masks (1 when both are empty)."""
    union = np.count_nonzero(found | truth)
    return float(np.count_nonzero(found & truth) / union) if union else 1.0


def render_paths(renders_dir: Path, every: int = 1, offset: int = 0) -> list[tuple[int, Path]]:
    """(index in the sorted listing, path) of every ``every``-th RGBA render from ``offset``."""
    paths = sorted(p for p in Path(renders_dir).glob("*.png") if not p.stem.endswith("_mask"))
    if not paths:
        raise InputError(f"no <id>.png renders in {renders_dir}")
    return every_nth(list(enumerate(paths)), every, offset)


def evaluate_masks(plugins: Plugins, family: str, renders_dir: Path, out_dir: Path,
                   backgrounds: Sequence[str] = BACKGROUNDS, every: int = 1, offset: int = 0, seed: int = 0,
                   debug: bool = False, settings: dict | None = None,
                   progress: Callable[[int], None] | None = None) -> list[MaskScore]:
    """Score the segmenter chain on every selected render over every background.

    Writes ``masks.csv`` (one row per composite) and ``summary.csv`` (per background)
    into ``out_dir``, and with ``debug`` a sheet per composite in ``out_dir/debug``:
    the input, the found mask (misses blue, false positives red) and the truth.
    """
    for kind in backgrounds:
        if kind not in BACKGROUNDS:
            raise ConfigError(f"unknown background {kind!r} (choose from {', '.join(BACKGROUNDS)})")
    fam = plugins.family(family)
    fam_settings = plugins.settings(fam.name, settings or {})
    selected = render_paths(renders_dir, every, offset)
    out_dir = Path(out_dir)
    (out_dir / "debug" if debug else out_dir).mkdir(parents=True, exist_ok=True)
    scores = []
    for index, path in selected:
        rgba = read_image(path)
        if rgba.ndim != 3 or rgba.shape[2] != 4:
            raise InputError(f"{path} has no alpha channel: the benchmark needs RGBA renders")
        truth = rgba[..., 3] > 127
        for kind in backgrounds:
            photo = composite_photo(rgba, kind, np.random.default_rng([seed, index, BACKGROUNDS.index(kind)]))
            report = Report()
            start = time.perf_counter()
            try:
                found = segment_object(plugins, photo, fam, fam_settings, report=report).object_mask
                error = ""
            except Frontal3DError as exc:
                found, error = np.zeros_like(truth), str(exc)
            score = MaskScore(fam.name, path.stem, kind, round(mask_iou(found, truth), 4), round(time.perf_counter() - start, 3),
                              str(report.data.get("segmenter", "")), error)
            scores.append(score)
            if debug:
                cv2.imwrite(str(out_dir / "debug" / f"{path.stem}_{kind}.png"), _debug_sheet(photo, found, truth))
            if progress:
                progress(1)
    _write(out_dir, scores)
    return scores


def _debug_sheet(photo: np.ndarray, found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """BGR sheet: input | found mask (white; missed object pixels blue, extra pixels red) | truth."""
    mask_view = np.zeros(photo.shape, np.uint8)
    mask_view[found & truth] = 255
    mask_view[truth & ~found] = (255, 80, 0)
    mask_view[found & ~truth] = (0, 0, 255)
    panels = [cv2.cvtColor(photo, cv2.COLOR_RGB2BGR), mask_view, np.repeat(truth[..., None], 3, axis=2).astype(np.uint8) * 255]
    scale = SHEET_PANEL / max(photo.shape[:2])
    size = (max(1, round(photo.shape[1] * scale)), max(1, round(photo.shape[0] * scale)))
    return np.hstack([cv2.resize(panel, size, interpolation=cv2.INTER_AREA) for panel in panels])


def _write(out_dir: Path, scores: list[MaskScore]) -> None:
    write_csv(out_dir / "masks.csv", tuple(field.name for field in fields(MaskScore)), [asdict(score) for score in scores])
    with (out_dir / "summary.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(("family", "background", "images", "mean_iou", "median_iou", "min_iou", f"below_{TARGET_IOU}", "failed", "mean_seconds"))
        for (family, kind), members in _by_background(scores).items():
            ious = [s.iou for s in members]
            writer.writerow((family, kind, len(members), round(statistics.fmean(ious), 4), round(statistics.median(ious), 4), round(min(ious), 4),
                             sum(iou < TARGET_IOU for iou in ious), sum(bool(s.error) for s in members),
                             round(statistics.fmean(s.seconds for s in members), 3)))


def _by_background(scores: list[MaskScore]) -> dict[tuple[str, str], list[MaskScore]]:
    groups: dict[tuple[str, str], list[MaskScore]] = {}
    for score in scores:
        groups.setdefault((score.family, score.background), []).append(score)
    return groups


def summary_lines(scores: list[MaskScore]) -> list[str]:
    """One line per background: images, mean (median) IoU, worst, how many miss the target, failures, time."""
    lines = [f"{'family':<10}{'background':<12}{'n':>4}{'mean (median)':>18}{'min':>8}{'< ' + str(TARGET_IOU):>8}{'failed':>8}{'s/image':>9}"]
    for (family, kind), members in _by_background(scores).items():
        ious = [s.iou for s in members]
        cell = f"{statistics.fmean(ious):.3f} ({statistics.median(ious):.3f})"
        lines.append(f"{family:<10}{kind:<12}{len(members):>4}{cell:>18}{min(ious):>8.3f}{sum(i < TARGET_IOU for i in ious):>8}"
                     f"{sum(bool(s.error) for s in members):>8}{statistics.fmean(s.seconds for s in members):>9.2f}")
    return lines
