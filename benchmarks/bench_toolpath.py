"""Toolpath: artwork -> mask -> ordered toolpath, step by step, on two inputs.

Inputs: the built-in emblem, and a generated logo (:func:`logo_svg`: 150 x 40 mm, twelve
filled regions, two of them with holes; the layout of the original's ROS logo: a 3 x 3
grid of dots, then R, O and S). Each chain runs ``repeat`` times; every row is the median
over those runs of one step, all measured in the same runs:

* ``artwork``: load and rasterise (:func:`~tattotronix.art.artwork.load_artwork`);
* ``mask``: threshold and drop small regions (:func:`~tattotronix.art.mask.make_mask`);
* ``toolpath``: :func:`~tattotronix.path.plan.plan_toolpath`, and its sub-steps as it
  times them itself (:attr:`~tattotronix.path.plan.Toolpath.timings_s`): checks, regions
  (labelling and tracing), fill (the strokes from the regions: outlines, fill, and with
  compensation its distance fields and line art), resampling, costs, ordering, the
  original's rule (its 3-D path and metrics), our path, metrics;
* ``total``: the three above, with its ratio to the original's published 0.056 s.

When the art library is missing, a synthetic mask of rings, bars and dots stands in for
the artwork and mask steps, and the note says so.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from run import Row, median_time

from tattotronix.art.grid import InkMask
from tattotronix.config.schema import MaskConfig, PanelConfig, ToolpathConfig
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import Toolpath, plan_toolpath

#: the original's scripts, artwork to ordered toolpath (median, published)
ORIGINAL_CHAIN_S = 0.056

LOGO_WIDTH_MM, LOGO_HEIGHT_MM = 150, 40


def logo_svg() -> str:
    """A logo-like SVG, 150 x 40 mm: twelve filled regions, two with holes (deterministic).

    Nine dots (3 x 3, radius 5 mm), then three letters drawn as 6 mm strokes: an R (its
    bowl is a counter), an O (an elliptic ring) and an S. No background: the canvas is
    transparent, as a logo's usually is.
    """
    dots = "\n".join(
        f'    <circle cx="{x}" cy="{y}" r="5"/>' for x in (8, 20, 32) for y in (8, 20, 32)
    )
    w, h = LOGO_WIDTH_MM, LOGO_HEIGHT_MM
    return f"""<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}"
     width="{w}mm" height="{h}mm">
  <title>benchmark logo: dots, R, O, S</title>
  <g fill="black">
{dots}
  </g>
  <g fill="none" stroke="black" stroke-width="6" stroke-linejoin="miter">
    <path d="M 47 37 V 4 H 57 A 8 8 0 0 1 57 20 H 47 M 55 20 L 68 37"/>
    <ellipse cx="96" cy="20" rx="10" ry="15"/>
    <path d="M 140 9 C 136 3, 118 3, 118 11 C 118 19, 140 16, 140 27 C 140 37, 121 37, 117 31"/>
  </g>
</svg>
"""


def _synthetic(res_mm: float) -> InkMask:
    h, w = 352, 600
    yy, xx = np.mgrid[0:h, 0:w]
    ink = np.zeros((h, w), bool)
    for cx in range(50, w - 40, 75):
        for cy in (70, 176, 282):
            r = np.hypot(xx - cx, yy - cy)
            ink |= ((r <= 30) & (r >= 15)) | ((np.abs(xx - cx) <= 4) & (np.abs(yy - cy) <= 40))
    return InkMask.centred(ink, res_mm)


def _chain(source: Path | None, mcfg: MaskConfig, params: ToolpathParams
           ) -> Callable[[], tuple[dict[str, float], Toolpath]]:
    """One run of the chain: (step -> wall time, s), and the toolpath."""
    def run() -> tuple[dict[str, float], Toolpath]:
        times: dict[str, float] = {}
        t0 = time.perf_counter()
        try:
            from tattotronix.art.artwork import load_artwork
            from tattotronix.art.mask import make_mask
        except ImportError:
            mask = _synthetic(mcfg.res_mm)
        else:
            art = load_artwork(source, mcfg.width_mm, mcfg.res_mm, 40_000_000,
                               default_width_mm=mcfg.default_width_mm)
            t1 = time.perf_counter()
            times["artwork"] = t1 - t0
            mask = make_mask(art.grey, mcfg.res_mm, mcfg.method, mcfg.min_region_mm2)[0]
            t0 = time.perf_counter()
            times["mask"] = t0 - t1
        tp = plan_toolpath(mask, params)
        times["toolpath"] = time.perf_counter() - t0
        times.update({f"toolpath: {k}": v for k, v in getattr(tp, "timings_s", {}).items()})
        times["total"] = sum(times.get(k, 0.0) for k in ("artwork", "mask", "toolpath"))
        return times, tp
    return run


def _rows(what: str, runs: list[dict[str, float]], tp: Toolpath) -> list[Row]:
    rows: list[Row] = []
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    for k, v in med.items():
        note = ""
        if k == "total":
            note = (f"{v / ORIGINAL_CHAIN_S:.2f}x the original's {ORIGINAL_CHAIN_S} s "
                    f"(target <= 0.05 s)")
        elif k == "toolpath: ordering":
            note = f"{tp.ordering.passes} 2-opt passes"
        rows.append((f"{what}: {k}", v, "s", note))
    m, o = tp.metrics, tp.original
    rows.append((f"{what}: points per second (toolpath)", m.points / med["toolpath"],
                 "points/s", f"{len(tp.drawing.strokes)} strokes, {m.points} points"))
    rows.append((f"{what}: planned time, ours", m.time_s, "s",
                 f"{m.entries} entries, {m.travel_mm:.0f} mm travel"))
    rows.append((f"{what}: planned time, original order", o.time_s, "s",
                 f"{o.entries} entries, {o.travel_mm:.0f} mm travel; "
                 f"ours is {m.time_s / o.time_s:.3f}x"))
    return rows


def bench(repeat: int) -> list[Row]:
    mcfg = MaskConfig()
    params = ToolpathParams.from_settings(ToolpathConfig(), mcfg, PanelConfig())
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        logo = Path(tmp) / "logo.svg"
        logo.write_text(logo_svg())
        for what, source in (("emblem", None), ("logo", logo)):
            rows += _rows(what, *_runs(_chain(source, mcfg, params), repeat))
    return rows


def _runs(run: Callable[[], tuple[dict[str, float], Toolpath]], repeat: int
          ) -> tuple[list[dict[str, float]], Toolpath]:
    """``repeat`` runs of the chain (after one to warm up): their step times, the last
    toolpath."""
    run()  # warm up: imports, first-call caches
    runs: list[dict[str, float]] = []
    tps: list[Toolpath] = []

    def once() -> None:
        times, tp = run()
        runs.append(times)
        tps[:] = [tp]

    median_time(once, max(repeat, 1))
    return runs, tps[0]
