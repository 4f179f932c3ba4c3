"""Benchmark: a full `dvc repro` from a clean clone, and the time of each stage.

    python benchmarks/run.py --repeat 1 repro      # target: under 10 min on 2 cores

The clone is made from the current commit (``git clone`` of this repository) in a
temporary folder, so nothing is cached; the stages run one after another, as DVC runs
them. A stage's time is from its "Running stage" line to the next one (DVC's own
bookkeeping included). A second, no-op ``dvc repro`` is timed too (target: under 5 s).
Each repeat is a fresh clone; the medians are reported.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

Row = tuple[str, float, str, str]


def _timed_repro(clone: Path) -> tuple[float, dict[str, float], int]:
    """(total s, stage -> s, exit code) of one streamed `dvc repro`."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "dvc", "repro"], cwd=clone, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    assert proc.stdout is not None
    stages: dict[str, float] = {}
    current, since = None, t0
    for line in proc.stdout:
        if line.startswith("Running stage '"):
            now = time.perf_counter()
            if current is not None:
                stages[current] = now - since
            current, since = line.split("'")[1], now
    rc = proc.wait()
    end = time.perf_counter()
    if current is not None:
        stages[current] = end - since
    return end - t0, stages, rc


def bench(repeat: int) -> list[Row]:
    totals, noops = [], []
    per_stage: dict[str, list[float]] = defaultdict(list)
    for _ in range(max(1, repeat)):
        with tempfile.TemporaryDirectory() as tmp:
            clone = Path(tmp) / "clone"
            subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
            total, stages, rc = _timed_repro(clone)
            if rc != 0:
                raise SystemExit(f"dvc repro failed in the clean clone (exit {rc})")
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "dvc", "repro"], cwd=clone, check=True,
                           capture_output=True)
            noops.append(time.perf_counter() - t0)
            totals.append(total)
            for name, s in stages.items():
                per_stage[name].append(s)
    rows: list[Row] = [("dvc repro, clean clone", statistics.median(totals), "s",
                        f"target < 600 s ({statistics.median(totals) / 600:.2f} of it)"),
                       ("dvc repro, no-op", statistics.median(noops), "s", "target < 5 s")]
    groups: dict[str, float] = defaultdict(float)
    for name, vals in per_stage.items():
        groups[name.split("@")[0]] += statistics.median(vals)
    for name, vals in sorted(per_stage.items(), key=lambda kv: -statistics.median(kv[1])):
        rows.append((f"  stage {name}", statistics.median(vals), "s", ""))
    for name, s in sorted(groups.items(), key=lambda kv: -kv[1]):
        rows.append((f"  group {name}", s, "s", f"{s / statistics.median(totals):.0%}"))
    return rows
