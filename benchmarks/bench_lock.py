"""Benchmark: what DVC does with ``dvc.lock`` after every stage, on this lock and on the
lock before one-stamp-per-stage code deps.

    python benchmarks/run.py lock            # the committed lock against HEAD's of 3c04f89^

After each stage DVC reads the whole lock with ruamel.yaml's round-trip loader, updates
the stage's entry and streams the whole document back into the file it has just
truncated (``dvc/utils/serialize/_common.py``): the dump is the window in which a Ctrl-C
cuts the lock short. Rows: the lock's lines, the read and the write (median), as DVC does
them, and the ratios to the older lock.
"""

from __future__ import annotations

import io
import subprocess
from pathlib import Path

from run import median_time

ROOT = Path(__file__).resolve().parents[1]
#: the commit before the code deps became one stamp per stage
BEFORE = "6a857df"

Row = tuple[str, float, str, str]


def _lock_at(rev: str | None) -> str:
    if rev is None:
        return (ROOT / "dvc.lock").read_text(encoding="utf-8")
    return subprocess.run(["git", "show", f"{rev}:dvc.lock"], cwd=ROOT, capture_output=True,
                          text=True, check=True).stdout


def _dvc_read_write(text: str, repeat: int) -> tuple[float, float]:
    from dvc.utils.serialize import parse_yaml_for_update
    from dvc.utils.serialize._yaml import _dump

    read, data = median_time(lambda: parse_yaml_for_update(text, "dvc.lock"), repeat)
    write, _ = median_time(lambda: _dump(data, io.StringIO()), repeat)
    return read, write


def bench(repeat: int) -> list[Row]:
    rows: list[Row] = []
    before = _lock_at(BEFORE)
    now = _lock_at(None)
    r0, w0 = _dvc_read_write(before, repeat)
    r1, w1 = _dvc_read_write(now, repeat)
    n0, n1 = len(before.splitlines()), len(now.splitlines())
    rows.append(("dvc.lock lines (now / before)", n1, "lines",
                 f"{n0} before: {n0 / n1:.1f}x fewer"))
    rows.append(("dvc.lock read, as DVC reads it after a stage", r1, "s",
                 f"{r0:.3f} s before: {r0 / r1:.1f}x faster"))
    rows.append(("dvc.lock write: the Ctrl-C window", w1, "s",
                 f"{w0:.3f} s before: {w0 / w1:.1f}x shorter"))
    return rows
