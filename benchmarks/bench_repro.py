"""Benchmark: a full `dvc repro` from a clean clone, and the time of each stage.

    python benchmarks/run.py --repeat 1 repro      # target (issue 29): 150 s on 2 cores

The clone is made from the current commit (``git clone`` of this repository) in a
temporary folder, so nothing is cached; the stages run one after another, as DVC runs
them. A stage's time is from its "Running stage" line to the next one (DVC's own
bookkeeping included); its work is what the stage itself reports (``<stage>: done in
X s``), and the rest is overhead: the Python process starting (imports, the settings)
and DVC's bookkeeping (hashing, rewriting ``dvc.lock``). A second, no-op ``dvc repro`` is
timed too (target: 2 s). Each repeat is a fresh clone; the medians are reported.
"""

from __future__ import annotations

import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

Row = tuple[str, float, str, str]

#: the line a stage ends with (``tattotronix/stage.py``)
_DONE = re.compile(r"\[tattotronix\] [\w-]+: done in ([0-9.]+) s")


def _timed_repro(clone: Path) -> tuple[float, dict[str, float], dict[str, float], int]:
    """(total s, stage -> s, stage -> its own work s, exit code) of one streamed
    `dvc repro`."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "dvc", "repro"], cwd=clone, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    assert proc.stdout is not None
    stages: dict[str, float] = {}
    work: dict[str, float] = {}
    current, since = None, t0
    for line in proc.stdout:
        done = _DONE.match(line)
        if done and current is not None:
            work[current] = float(done.group(1))
        if line.startswith("Running stage '"):
            now = time.perf_counter()
            if current is not None:
                stages[current] = now - since
            current, since = line.split("'")[1], now
    rc = proc.wait()
    end = time.perf_counter()
    if current is not None:
        stages[current] = end - since
    return end - t0, stages, work, rc


def bench(repeat: int) -> list[Row]:
    totals, noops = [], []
    works: list[float] = []
    overheads: list[float] = []
    counts: list[int] = []
    per_stage: dict[str, list[float]] = defaultdict(list)
    for _ in range(max(1, repeat)):
        with tempfile.TemporaryDirectory() as tmp:
            clone = Path(tmp) / "clone"
            subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
            total, stages, work, rc = _timed_repro(clone)
            if rc != 0:
                raise SystemExit(f"dvc repro failed in the clean clone (exit {rc})")
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "dvc", "repro"], cwd=clone, check=True,
                           capture_output=True)
            noops.append(time.perf_counter() - t0)
            totals.append(total)
            works.append(sum(work.values()))
            overheads.append(sum(stages[n] - work.get(n, 0.0) for n in stages))
            counts.append(len(stages))
            for name, s in stages.items():
                per_stage[name].append(s)
    total = statistics.median(totals)
    n = statistics.median(counts)
    overhead = statistics.median(overheads)
    rows: list[Row] = [("dvc repro, clean clone", total, "s",
                        f"target 150 s ({total / 150:.2f} of it)"),
                       ("  the stages' own work", statistics.median(works), "s",
                        f"{statistics.median(works) / total:.0%}"),
                       ("  overhead (start-up, DVC)", overhead, "s",
                        f"{overhead / total:.0%}; {overhead / max(n, 1):.2f} s a stage, "
                        f"{n:.0f} stages"),
                       ("dvc repro, no-op", statistics.median(noops), "s", "target 2 s")]
    groups: dict[str, float] = defaultdict(float)
    for name, vals in per_stage.items():
        groups[name.split("@")[0]] += statistics.median(vals)
    for name, vals in sorted(per_stage.items(), key=lambda kv: -statistics.median(kv[1])):
        rows.append((f"  stage {name}", statistics.median(vals), "s", ""))
    for name, s in sorted(groups.items(), key=lambda kv: -kv[1]):
        rows.append((f"  group {name}", s, "s", f"{s / statistics.median(totals):.0%}"))
    return rows
