"""Stage ``artwork``: a PNG, JPG or SVG file (or a built-in) to a grey raster on the mask grid.

Writes ``data/artwork/<name>.png`` (8-bit grey, on the mask grid: ``mask.width_mm`` wide,
or an SVG's own physical width, at ``mask.res_mm`` per pixel or finer for thin strokes;
tattotronix/art/sizing.py) and ``data/metrics/artwork/<name>.json``. ``artwork.source``
picks the file (null: the built-in emblem; ``portrait``: the built-in photograph);
``artwork.name`` names the outputs and defaults to the file's stem. With
``artwork.vector=true`` an SVG's stroked lines are also written, from its geometry, to
``data/artwork/<name>-lines.npz`` (empty otherwise; tattotronix/art/vector.py).
"""

from __future__ import annotations

# first: a Ctrl-C while the libraries below import ends in one line (tattotronix/__init__.py)
import tattotronix  # noqa: F401

# isort: split
import logging

from tattotronix.app.records import save_artwork
from tattotronix.art.artwork import artwork_name, check_same_source, load_artwork
from tattotronix.art.mask import otsu_ink
from tattotronix.art.vector import VectorLines, artwork_lines
from tattotronix.config.schema import Config
from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.stages.artwork")


def main(cfg: Config, out: Outputs) -> None:
    """Load the artwork, write its raster and metrics."""
    name = artwork_name(cfg.artwork)
    if cfg.artwork.name is None:  # a name from the file's stem: mine.png and mine.svg
        check_same_source(out.path("metrics", "artwork", f"{name}.json"), cfg.artwork.source,
                          name, replacing=True)
    art = load_artwork(
        cfg.artwork.source, cfg.mask.width_mm, cfg.mask.res_mm, cfg.artwork.max_pixels, name,
        svg_local_files=cfg.artwork.svg_local_files,
        default_width_mm=cfg.mask.default_width_mm, min_line_px=cfg.mask.min_line_px,
        height_mm=cfg.mask.height_mm,
    )
    ink, _, _ = otsu_ink(art.grey)
    lines = (artwork_lines(cfg.artwork.source, art.shape, art.res_mm, cfg.toolpath.step_mm)
             if cfg.artwork.vector else VectorLines.empty())
    png, _ = save_artwork(out, name, art, lines)
    width_mm, height_mm = art.size_mm
    out.write_json(
        out.path("metrics", "artwork", f"{name}.json"),
        {
            "name": name,
            "source": art.source,
            "kind": art.kind,
            "original_px": list(art.original_px),
            "render_px": list(art.render_px) if art.render_px else None,
            "raster_px": [art.shape[1], art.shape[0]],
            "res_mm": art.res_mm,
            "width_mm": width_mm,
            "height_mm": height_mm,
            "ink_fraction": float(ink.mean()),
            "vector_lines": len(lines.paths),
            "transparent": art.transparent,
        },
    )
    log.info("artwork %s: %s (%.1f x %.1f mm, ink ~%.1f %%)", name, png, width_mm,
             height_mm, 100.0 * ink.mean())


if __name__ == "__main__":
    run_stage("artwork", main)
