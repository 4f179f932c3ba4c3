"""Stage ``fills``: the fill styles side by side on one artwork (docs/toolpath.md, "Fill
styles"; tattotronix/path/fillstyles.py).

Reads ``data/mask/<name>.npz`` (and, with ``artwork.vector``, the artwork's lines), plans
it once per case of ``study.fills.cases`` and writes ``data/figures/<name>/fills.png``
(the same square of each plan's ink over the artwork, and the share inked against the
planned time) and ``data/metrics/fills/<name>.json``. Nothing else: the pipeline's
toolpath stays the ``toolpath`` stage's.
"""

from __future__ import annotations

import logging

from tattotronix.art.artwork import artwork_name
from tattotronix.art.stored import stored_artwork
from tattotronix.config.schema import Config
from tattotronix.io.outputs import Outputs
from tattotronix.path.fillstyles import compare_fill_styles, fills_figure
from tattotronix.path.params import ToolpathParams
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.stages.fills")


def main(cfg: Config, out: Outputs) -> None:
    """Plan every fill style of ``study.fills``; write the figure and the metrics."""
    name = artwork_name(cfg.artwork)
    stored = stored_artwork(out, name, bool(cfg.artwork.vector))
    params = ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel)
    cases = {k: (c.fill_style.name, float(c.fill_angle_deg))
             for k, c in cfg.study.fills.cases.items()}
    result = compare_fill_styles(stored.mask, params, cases,
                                 float(cfg.toolpath.needle_width_mm),
                                 float(cfg.toolpath.ink_res_mm), name, stored.vector)
    fills_figure(result, float(cfg.study.fills.zoom_mm),
                 out.tmp_path(out.path("figures", name, "fills.png")))
    out.write_json(out.path("metrics", "fills", f"{name}.json"), result.metrics())
    for c in result.cases:
        log.info("fills %s: %-12s %5.1f %% inked, %6.1f s (%.2fx), %d entries", name,
                 c.label(), 100 * c.ink.fidelity.coverage, c.time_s,
                 c.time_s / result.cases[0].time_s, c.entries)


if __name__ == "__main__":
    run_stage("fills", main)
