"""Stage ``toolpath``: the ink mask to the ordered 3-D needle path.

Reads ``data/mask/<name>.npz`` (run the ``mask`` stage first) and, with ``artwork.vector``,
the artwork's vector lines ``data/artwork/<name>-lines.npz``, and writes
``data/toolpath/<name>.npz`` (``uvz_mm``, ``kind``, ``xyz_m``, ``stroke``, ``t_s``, and per
drawn stroke ``stroke_kind``, ``stroke_region`` and ``stroke_width_mm``; ``provenance``),
the same plan as an SVG in millimetres ``data/toolpath/<name>.svg`` (the panel as the
page, one layer per stroke kind, drags and travel: tattotronix/path/export.py), the
figures ``data/figures/<name>/toolpath.png`` and ``data/figures/<name>/artwork_ink.png``
(the planned ink over the artwork, bleed in red) and ``data/metrics/toolpath/<name>.json``
(ours and, under ``original_order``, the same figures for the original's ordering rule;
under ``artwork``, the planned ink against the artwork: tattotronix/path/fidelity.py).
"""

from __future__ import annotations

# first: a Ctrl-C while the libraries below import ends in one line (tattotronix/__init__.py)
import tattotronix  # noqa: F401

# isort: split
import logging

from tattotronix.app.records import save_toolpath
from tattotronix.art.artwork import artwork_name
from tattotronix.art.stored import stored_artwork
from tattotronix.config.schema import Config
from tattotronix.io.outputs import Outputs
from tattotronix.path.export import panel_extent_mm, toolpath_svg
from tattotronix.path.fidelity import missed_message
from tattotronix.path.figure import toolpath_figure
from tattotronix.path.inkfigure import artwork_ink_figure
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import check_needle, plan_toolpath
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.stages.toolpath")


def main(cfg: Config, out: Outputs) -> None:
    """Plan the toolpath of one artwork's mask; write the path, figure and metrics."""
    name = artwork_name(cfg.artwork)
    # refuses a missing or corrupt file by name
    stored = stored_artwork(out, name, bool(cfg.artwork.vector))
    mask = stored.mask
    params = ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel)
    tp = plan_toolpath(mask, params, vector=stored.vector)
    needle = float(cfg.toolpath.needle_width_mm)
    ink = tp.ink(mask, needle, float(cfg.toolpath.ink_res_mm))
    # a needle that cannot draw the artwork is refused before anything is written
    check_needle(tp, mask, needle, float(cfg.toolpath.ink_res_mm), ink.fidelity)

    save_toolpath(out, cfg, name, tp, stored.inputs)
    out.write_text(out.path("toolpath", f"{name}.svg"),
                   toolpath_svg(tp, needle, panel_extent_mm(params.panel_size_mm), name))
    toolpath_figure(
        tp, params.panel_size_mm, out.tmp_path(out.path("figures", name, "toolpath.png")), name
    )
    figure = out.path("figures", name, "artwork_ink.png")
    artwork_ink_figure(ink.art, ink.ink, ink.grid,
                       out.tmp_path(figure),
                       f"{name}: the planned ink against the artwork (needle "
                       f"{float(cfg.toolpath.needle_width_mm):g} mm wide)", ink.fidelity)
    missed, reach = ink.missed_by(params.pitch_mm, needle, mask.res_mm, params.lines_only)
    if missed:
        log.warning("toolpath %s", missed_message(name, missed, reach, str(figure)))
    out.write_json(out.path("metrics", "toolpath", f"{name}.json"),
                   {"name": name, **tp.metrics_dict(),
                    "artwork": {**ink.fidelity.metrics(), "missed_parts": len(missed),
                                "missed": [p.metrics() for p in missed]}})
    out.write_timings("toolpath", name, {"ordering_s": tp.ordering.elapsed_s})
    m, o, f = tp.metrics, tp.original, ink.fidelity
    log.info("toolpath %s against the artwork: bleed %.1f %% (up to %.3f mm), coverage "
             "%.1f %%, edge error %.3f mm mean, %.3f mm worst", name, 100 * f.bleed_share,
             f.bleed_max_mm, 100 * f.coverage, f.edge_mean_mm, f.edge_max_mm)
    log.info(
        "toolpath %s: %d points, %.0f mm marked, %.0f mm travel, %d entries, %.1f s "
        "(original order: %.0f mm travel, %d entries, %.1f s)",
        name, m.points, m.marked_mm, m.travel_mm, m.entries, m.time_s, o.travel_mm, o.entries,
        o.time_s,
    )


if __name__ == "__main__":
    run_stage("toolpath", main)
