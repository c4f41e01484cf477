"""Region-segmentation benchmark: how well do the object's inner regions come out?

Synthetic samples (``frontal3d synth``) carry a true region map; the shared data has
none. Each frontal sample is reconstructed with its true mask and its true subtype (so
the figures measure the region stage, not the gate or the subtype pick), and the
pipeline's region map on its working grid is compared with the true map brought onto
the same grid: per-region IoU, pooled over samples, and each sample's mean over the
regions it or the truth shows. The aligned template's transferred map (the prior the
refinement starts from) is scored too, so the refinement's own gain is visible.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from frontal3d.errors import Frontal3DError, InputError
from frontal3d.evaluate import write_csv
from frontal3d.pipeline import reconstruct
from frontal3d.plugins import Plugins
from frontal3d.synth import read_labels_of, read_sample, read_sample_regions

#: The two region maps scored (the pipeline's map name -> CSV column, summary label):
#: the template's prior and the pipeline's result.
MAPS = {"transferred_regions": ("transferred_miou", "template transfer"), "regions": ("miou", "pipeline")}
CSV_FIELDS = ("id", "subtype", "transferred_miou", "miou", "seconds", "error")


@dataclass(frozen=True)
class RegionSummary:
    """Mean per-sample mIoU of each map and per-region IoU pooled over samples."""

    scored: int
    failed: int
    mean_miou: dict[str, float]  # by map name
    region_iou: dict[str, dict[str, float]]  # map name -> region name -> pooled IoU

    def lines(self) -> list[str]:
        out = [f"samples scored: {self.scored}" + (f" ({self.failed} failed)" if self.failed else "")]
        for name, (_, label) in MAPS.items():
            regions = ", ".join(f"{region} {iou:.3f}" for region, iou in self.region_iou[name].items())
            out.append(f"{label}: mean IoU {self.mean_miou[name]:.3f} ({regions})")
        return out


def region_ious(predicted: np.ndarray, truth: np.ndarray, n_regions: int) -> tuple[np.ndarray, np.ndarray]:
    """(intersection, union) pixel counts per region label, over pixels either map puts in the object."""
    inter = np.array([np.count_nonzero((predicted == k) & (truth == k)) for k in range(n_regions)])
    union = np.array([np.count_nonzero((predicted == k) | (truth == k)) for k in range(n_regions)])
    return inter, union


def truth_on_working_grid(truth: np.ndarray, crop: dict, working_size: list[int]) -> np.ndarray:
    """The true region map cut to the pipeline's crop and resized (nearest) to its working grid."""
    cut = truth[crop["y"]: crop["y"] + crop["height"], crop["x"]: crop["x"] + crop["width"]]
    width, height = working_size
    return cv2.resize((cut + 1).astype(np.uint8), (width, height), interpolation=cv2.INTER_NEAREST).astype(np.int64) - 1


def evaluate_regions_on_synth(plugins: Plugins, family: str, data_dir: Path, out_dir: Path | None = None,
                              limit: int | None = None, settings: dict | None = None,
                              progress: Callable[[int], None] | None = None) -> tuple[list[dict], RegionSummary]:
    """Score the region maps of the first ``limit`` frontal samples of a synth folder; writes
    ``regions.csv`` and ``summary.txt`` into ``out_dir`` when given."""
    data_dir = Path(data_dir)
    labels = read_labels_of(data_dir, family)
    frontal = [label for label in labels if int(label["frontal"])][:limit]
    if not frontal:
        raise InputError(f"{data_dir}: no frontal samples to score regions on")
    fam = plugins.family(family)
    names = {subtype: fam.regions[subtype] for subtype in fam.subtypes}
    pooled = {name: {} for name in MAPS}  # map -> region name -> [intersection, union]
    rows = []
    for label in frontal:
        row = {"id": label["file"], "subtype": label["subtype"], "error": ""}
        start = time.perf_counter()
        try:
            image, mask = read_sample(data_dir, label["file"])
            result = reconstruct(image, family, mask=mask, subtype=label["subtype"], plugins=plugins, **(settings or {}))
            truth = truth_on_working_grid(read_sample_regions(data_dir, label["file"]), result.report["crop"], result.report["working_size"])
            region_names = names[label["subtype"]]
            for name, (column, _) in MAPS.items():
                inter, union = region_ious(result.maps[name], truth, len(region_names))
                shown = union > 0
                row[column] = round(float(np.mean(inter[shown] / union[shown])), 4)
                for region, i, u in zip(region_names, inter, union):
                    counts = pooled[name].setdefault(region, [0, 0])
                    counts[0] += int(i)
                    counts[1] += int(u)
        except Frontal3DError as error:  # a sample the chain turns down is recorded, not fatal
            row["error"] = str(error).splitlines()[0]
        row["seconds"] = round(time.perf_counter() - start, 3)
        rows.append(row)
        if progress:
            progress(1)
    scored = [row for row in rows if not row["error"]]
    if not scored:
        raise InputError(f"{data_dir}: no sample could be scored ({rows[0]['error']})")
    summary = RegionSummary(
        scored=len(scored), failed=len(rows) - len(scored),
        mean_miou={name: float(np.mean([row[column] for row in scored])) for name, (column, _) in MAPS.items()},
        region_iou={name: {region: i / u for region, (i, u) in pooled[name].items() if u} for name in MAPS},
    )
    if out_dir is not None:
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        write_csv(out_dir / "regions.csv", CSV_FIELDS, rows)
        (out_dir / "summary.txt").write_text("\n".join(summary.lines()) + "\n")
    return rows, summary
