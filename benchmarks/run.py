"""Run every benchmark and print medians and ratios.

Each ``benchmarks/bench_<topic>.py`` defines ``bench(repeat: int) -> list[Row]`` where a
row is ``(name, median_value, unit, note)``. Timings inside are medians over ``repeat``
runs, so the figures hold on a shared, noisy machine; ratios compare against a baseline
measured in the same run. Usage::

    python benchmarks/run.py [--repeat 5] [topic ...]
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent

Row = tuple[str, float, str, str]


def median_time(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    """Median wall time of ``fn()`` over ``repeat`` calls, and the last result."""
    times, result = [], None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), result


def bench_main(bench: Callable[[int], list[Row]], doc: str, argv: Sequence[str] | None = None,
               repeat: int = 5) -> int:
    """A benchmark script's command line: ``--repeat N``, then its rows printed."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=repeat)
    args = ap.parse_args(argv)
    for name, value, unit, note in bench(args.repeat):
        print(f"{name:55s} {value:9.3f} {unit:2s}  {note}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("topics", nargs="*", help="bench_<topic>.py names; all by default")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    files = sorted(HERE.glob("bench_*.py"))
    if args.topics:
        files = [f for f in files if f.stem.removeprefix("bench_") in args.topics]
    if not files:
        print("no benchmarks found", file=sys.stderr)
        return 1
    print(f"{'benchmark':<48} {'median':>14}  unit  note")
    for f in files:
        spec = importlib.util.spec_from_file_location(f.stem, f)
        assert spec and spec.loader
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        for name, value, unit, note in mod.bench(args.repeat):
            label = f"{f.stem.removeprefix('bench_')}: {name}"
            print(f"{label:<48} {value:>14.6g}  {unit}  {note}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
