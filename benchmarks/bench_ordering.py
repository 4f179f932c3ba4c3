"""Stroke ordering on drawings of many strokes (a stipple or hatching SVG has thousands).

A generated SVG of short stroked lines (0.4 mm wide, 0.8 to 3 mm long, at random places
and angles on a 150 x 100 mm field) is planned in vector mode, as the toolpath stage
plans it (:func:`~tattotronix.app.pipeline.drawing_inputs`, then
:func:`~tattotronix.path.plan.plan_toolpath`); each line is a stroke. Rows, medians over
``repeat`` runs:

* ``<n> strokes, ordering``: the time :func:`~tattotronix.path.order.optimise_order` took,
  its 2-opt passes scoring every move until ``TWO_OPT_FULL_WORK`` move scores, then
  neighbour lists;
* ``<n> strokes, full 2-opt``: the same drawing with every move of every pass scored (no
  such limit), with the ratio of the two times and of the
  two plans' time between strokes (what the neighbour lists give up). On the larger
  drawing only: it takes about three minutes.

Usage::

    python benchmarks/run.py --repeat 3 ordering
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
from run import Row

import tattotronix.path.order as order_mod
from tattotronix.app.pipeline import drawing_inputs
from tattotronix.config.params import compose_settings
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import OrderResult, plan_toolpath

FIELD_MM = (150.0, 100.0)


def lines_svg(n: int, seed: int = 1) -> str:
    """``n`` short stroked lines at random places and angles (deterministic)."""
    rng = np.random.default_rng(seed)
    paths = []
    for _ in range(n):
        x, y = rng.uniform(5, FIELD_MM[0] - 5), rng.uniform(5, FIELD_MM[1] - 5)
        a, length = rng.uniform(0, math.pi), rng.uniform(0.8, 3.0)
        paths.append(f'<path d="M{x:.2f},{y:.2f} L{x + length * math.cos(a):.2f},'
                     f'{y + length * math.sin(a):.2f}"/>')
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{FIELD_MM[0]:g}mm" '
            f'height="{FIELD_MM[1]:g}mm" viewBox="0 0 {FIELD_MM[0]:g} {FIELD_MM[1]:g}">'
            '<g fill="none" stroke="black" stroke-width="0.4">' + "".join(paths) +
            "</g></svg>")


def _order(svg: Path, full: bool) -> OrderResult:
    cfg = compose_settings([f"artwork.source={svg}", "artwork.vector=true"])
    mask, vector = drawing_inputs(cfg, svg, svg.stem)
    params = ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel)
    limit = order_mod.TWO_OPT_FULL_WORK
    order_mod.TWO_OPT_FULL_WORK = 10**15 if full else limit
    try:
        return plan_toolpath(mask, params, vector=vector).ordering
    finally:
        order_mod.TWO_OPT_FULL_WORK = limit


def bench(repeat: int) -> list[Row]:
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        for n, compare in ((5000, False), (10_000, True)):
            svg = Path(tmp) / f"lines{n}.svg"
            svg.write_text(lines_svg(n))
            runs = [_order(svg, False) for _ in range(max(repeat, 1))]
            o = runs[-1]
            t = float(np.median([r.elapsed_s for r in runs]))
            strokes = len(o.order.sequence)
            rows.append((f"{strokes} strokes, ordering", t, "s",
                         f"between strokes {o.cost_s:.1f} s (greedy {o.greedy_cost_s:.1f} s, "
                         f"original order {o.original_cost_s:.1f} s), {o.passes} 2-opt "
                         "passes"))
            if compare:
                full = _order(svg, True)
                rows.append((f"{strokes} strokes, full 2-opt", full.elapsed_s, "s",
                             f"{full.elapsed_s / t:.1f}x the time; its plan "
                             f"{full.cost_s:.1f} s between strokes; the neighbour lists' "
                             f"{o.cost_s / full.cost_s:.4f}x that"))
    return rows
