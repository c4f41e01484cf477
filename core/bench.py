"""``frontal3d bench``: per-stage seconds and peak memory of a reconstruction.

Speed is measured here, never by timed tests: run it on the machine you care about.
"""

from __future__ import annotations

import json
import resource
import statistics
import tempfile
import time
from pathlib import Path

from frontal3d.examples import example_image
from frontal3d.pipeline import reconstruct
from frontal3d.plugins import Plugins


def run_bench(plugins: Plugins, image: Path | None, family: str, mask: Path | None, repeat: int, as_json: bool = False) -> int:
    """Reconstruct and export ``image`` ``repeat`` times (the first run warms caches) and print a table."""
    if image is None:
        image, family = example_image(), "car" if family == "auto" else family
    runs = []
    with tempfile.TemporaryDirectory() as scratch:
        for run in range(max(1, repeat)):
            result = reconstruct(image, family, mask=mask, plugins=plugins)
            start = time.perf_counter()
            result.save(Path(scratch) / str(run))
            result.report["stages"]["export"] = round(time.perf_counter() - start, 4)
            result.report["peak_memory_mb"]["export"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
            runs.append(result.report)
    stages = list(runs[-1]["stages"])
    timed = runs[1:] if len(runs) > 1 else runs
    table = {
        stage: {
            "median_s": round(statistics.median(r["stages"][stage] for r in timed), 4),
            "peak_rss_mb": runs[-1]["peak_memory_mb"][stage],
        }
        for stage in stages
    }
    total = round(statistics.median(sum(r["stages"].values()) for r in timed), 3)
    peak = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    if as_json:
        print(json.dumps({"image": str(image), "runs": len(runs), "stages": table, "total_s": total, "peak_rss_mb": peak}, indent=2))
        return 0
    print(f"{image} ({runs[-1]['image_size'][0]}x{runs[-1]['image_size'][1]}, working {runs[-1]['working_size'][0]}x{runs[-1]['working_size'][1]}), {len(runs)} run(s), first run excluded from the medians")
    print(f"{'stage':<22}{'median s':>10}{'peak RSS MB':>14}")
    for stage, row in table.items():
        print(f"{stage:<22}{row['median_s']:>10.3f}{row['peak_rss_mb']:>14.1f}")
    print(f"{'total':<22}{total:>10.3f}{peak:>14.1f}")
    return 0
