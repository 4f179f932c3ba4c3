"""Studies: each closed-loop study's stage, every case at once, as ``dvc repro`` runs it.

    python benchmarks/run.py --repeat 1 studies     # target: the control study <= 20 s

Needs the stored drawing (``dvc repro`` makes ``data/trajectories/emblem.npz`` and
``data/ik/emblem.npz``). Each study's script runs as its DVC stage does
(``study.all_cases=true``), into a temporary data folder holding copies of the models and
the drawing, so nothing of the pipeline's is touched. The time is the whole command
(start-up and imports included). Beside it: the cases, the wall time per case, and the
study's own CPU time over its wall time (what running the cases concurrently buys; 1.0
would be one case after another).
"""

from __future__ import annotations

import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from run import Row

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"

#: study -> its stage script
SCRIPTS = {"control": "control_study", "approach": "approach", "resample": "resample",
           "rate": "rate", "timelaw": "timelaw"}


def _data_copy(folder: Path) -> Path:
    data = folder / "data"
    for rel in ("robot", "trajectories/emblem.npz", "ik/emblem.npz"):
        src, dst = DATA / rel, data / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        if src.is_dir():
            shutil.copytree(src, dst)
        else:
            shutil.copy2(src, dst)
    return data


def _cpu_of_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def bench(repeat: int) -> list[Row]:
    if not (DATA / "trajectories" / "emblem.npz").exists():
        return [("studies", float("nan"), "s", "data/trajectories/emblem.npz missing: run "
                 "dvc repro first")]
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        data = _data_copy(Path(tmp))
        for study, script in SCRIPTS.items():
            walls, cpus = [], []
            for _ in range(max(1, repeat)):
                cpu0 = _cpu_of_children()
                t0 = time.perf_counter()
                run = subprocess.run(
                    [sys.executable, f"stages/{script}.py", "artwork.name=emblem",
                     "study.all_cases=true", "draw.progress=false", f"paths.data={data}"],
                    cwd=ROOT, capture_output=True, text=True)
                walls.append(time.perf_counter() - t0)
                cpus.append(_cpu_of_children() - cpu0)
                if run.returncode != 0:
                    return [*rows, (f"{study} study", float("nan"), "s",
                                    run.stderr.strip().splitlines()[-1])]
            cases = len(list((data / "metrics" / study / "emblem").glob("*.json")))
            wall = statistics.median(walls)
            cpu = statistics.median(cpus)
            rows.append((f"{study} study, every case", wall, "s",
                         f"{cases} cases, {wall / max(cases, 1):.2f} s a case; CPU / wall "
                         f"{cpu / wall:.2f} (median of {len(walls)})"
                         + ("; target <= 20 s" if study == "control" else "")))
    return rows
