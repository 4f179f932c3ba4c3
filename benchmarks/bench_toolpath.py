"""Toolpath: artwork to toolpath on the built-in emblem, and points planned per second.

The mask comes from the art library (the built-in emblem at the default mask settings);
when the art library is missing, a synthetic mask of rings, bars and dots stands in and
the note says so.
"""

from __future__ import annotations

import numpy as np
from run import Row, median_time

from tattotronix.art.grid import InkMask
from tattotronix.config.schema import MaskConfig, PanelConfig, ToolpathConfig
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import plan_toolpath


def _synthetic(res_mm: float) -> InkMask:
    h, w = 352, 600
    yy, xx = np.mgrid[0:h, 0:w]
    ink = np.zeros((h, w), bool)
    for cx in range(50, w - 40, 75):
        for cy in (70, 176, 282):
            r = np.hypot(xx - cx, yy - cy)
            ink |= ((r <= 30) & (r >= 15)) | ((np.abs(xx - cx) <= 4) & (np.abs(yy - cy) <= 40))
    return InkMask.centred(ink, res_mm)


def bench(repeat: int) -> list[Row]:
    mcfg = MaskConfig()
    params = ToolpathParams.from_config(ToolpathConfig(), mcfg, PanelConfig())
    rows: list[Row] = []
    try:
        from tattotronix.art.artwork import load_artwork
        from tattotronix.art.mask import make_mask
    except ImportError:
        mask, what = _synthetic(mcfg.res_mm), "synthetic mask (art library missing)"
    else:
        def to_mask() -> InkMask:
            art = load_artwork(None, mcfg.width_mm, mcfg.res_mm, 40_000_000)
            return make_mask(art.grey, mcfg.res_mm, mcfg.method, mcfg.min_region_mm2)[0]

        t_mask, mask = median_time(to_mask, repeat)
        what = "built-in emblem"
        rows.append(("artwork -> mask", t_mask, "s", what))
    t_plan, tp = median_time(lambda: plan_toolpath(mask, params), repeat)
    m, o = tp.metrics, tp.original
    note = f"{what}: {len(tp.drawing.strokes)} strokes, {m.points} points"
    rows.append(("mask -> toolpath", t_plan, "s", note))
    if what == "built-in emblem":
        rows.append(("artwork -> toolpath", t_mask + t_plan, "s", what))
    rows.append(("points per second (mask -> toolpath)", m.points / t_plan, "points/s", note))
    rows.append(("ordering search", tp.ordering.elapsed_s, "s",
                 f"last run; {tp.ordering.passes} 2-opt passes"))
    rows.append(("planned time, ours", m.time_s, "s",
                 f"{m.entries} entries, {m.travel_mm:.0f} mm travel"))
    rows.append(("planned time, original order", o.time_s, "s",
                 f"{o.entries} entries, {o.travel_mm:.0f} mm travel; "
                 f"ours is {m.time_s / o.time_s:.3f}x"))
    return rows
