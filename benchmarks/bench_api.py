"""The Python API's latency: how long ``tattotronix.plan`` takes to answer, warm.

The browser front end (and a notebook) plan a drawing while the user waits. This times,
on the logo-sized SVG (150 x 40 mm, twelve regions, two holes; ``bench_toolpath.logo_svg``)
and on the built-in emblem, in one warm process (the imports and the first call paid):

* ``plan``: artwork to trajectory (:func:`tattotronix.plan`), and each step of it;
* ``stats``: the plan's figures (the planned ink against the artwork);
* ``preview``: the toolpath figure written as a PNG.

Goal (issue 31): a logo-sized SVG planned in 0.3 s or less on 2 cores, the preview in
0.2 s or less; the original's scripts took 0.06 to 0.09 s for their chain (artwork to
ordered toolpath, no IK or time law).

    python benchmarks/bench_api.py [--repeat 5]
    python benchmarks/run.py api
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from run import Row, bench_main, median_time

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_toolpath import logo_svg  # noqa: E402

import tattotronix as tt  # noqa: E402
from tattotronix.app.pipeline import drawing_inputs, solve_ik, trajectory_from_path  # noqa: E402
from tattotronix.config.params import compose_settings  # noqa: E402
from tattotronix.kinematics import Chain  # noqa: E402
from tattotronix.path.params import ToolpathParams  # noqa: E402
from tattotronix.path.plan import plan_toolpath  # noqa: E402
from tattotronix.robot.description import build_description  # noqa: E402
from tattotronix.trajectory import JointPath  # noqa: E402


def _steps(source: str, repeat: int) -> list[tuple[str, float]]:
    """The median time of each step of :func:`tattotronix.plan`, s."""
    cfg = compose_settings([f"artwork.source={source}"])
    desc = build_description(cfg.robot)
    chain = Chain.from_description(desc)
    name = Path(source).stem
    times: dict[str, list[float]] = {}

    def lap(key: str, t0: float) -> float:
        now = time.perf_counter()
        times.setdefault(key, []).append(now - t0)
        return now

    for _ in range(max(1, repeat)):
        t = time.perf_counter()
        mask, vector = drawing_inputs(cfg, source, name, desc)
        t = lap("artwork and mask", t)
        params = ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel)
        tp = plan_toolpath(mask, params, vector=vector)
        t = lap("toolpath", t)
        res = solve_ik(chain, tp.xyz_m, tp.path.uvz_mm, cfg.ik)
        tcp, _ = chain.fk(res.q)
        t = lap("IK", t)
        path = JointPath.from_arrays(desc.joint_names, res.q, tcp, tp.path.kind,
                                     tp.path.uvz_mm)
        trajectory_from_path(cfg, path, desc)
        lap("trajectory (time law, planned travel)", t)
    return [(k, float(np.median(v))) for k, v in times.items()]


def _rows(label: str, source: str, tmp: str, repeat: int) -> list[Row]:
    tt.plan(source, workdir=tmp)  # warm: imports, caches, the first call
    el, d = median_time(lambda: tt.plan(source, workdir=tmp), repeat)
    st = d.stats
    rows: list[Row] = [(f"plan [{label}]", el, "s",
                        f"{st['entries']} entries, {st['points']} points, "
                        f"{st['duration_s']:.0f} s drawing; goal <= 0.3 s for the logo")]
    for step, t in _steps(source, repeat):
        rows.append((f"  {step} [{label}]", t, "s", f"{t / el:.0%} of plan"))
    el_s, _ = median_time(d.figures, repeat)
    rows.append((f"stats [{label}]", el_s, "s", "the planned ink against the artwork"))
    png = Path(tmp) / f"{label}.png"
    el_p, _ = median_time(lambda: d.preview(png), repeat)
    rows.append((f"preview [{label}]", el_p, "s", "goal <= 0.2 s"))
    return rows


def bench(repeat: int) -> list[Row]:
    with tempfile.TemporaryDirectory() as tmp:
        logo = Path(tmp) / "logo.svg"
        logo.write_text(logo_svg())
        return [*_rows("logo SVG", str(logo), tmp, repeat),
                *_rows("emblem", "emblem", tmp, repeat)]


def main(argv: Sequence[str] | None = None) -> int:
    return bench_main(bench, __doc__ or "", argv, repeat=5)


if __name__ == "__main__":
    raise SystemExit(main())
