"""Stage ``mask``: the artwork raster to an ink mask on the panel grid.

Reads ``data/artwork/<name>.png`` (run the ``artwork`` stage first) and writes
``data/mask/<name>.npz`` (:class:`~tattotronix.art.grid.InkMask`, with its provenance),
a preview
``data/mask/<name>.png`` (ink black on white) and ``data/metrics/mask/<name>.json``.
"""

from __future__ import annotations

# first: a Ctrl-C while the libraries below import ends in one line (tattotronix/__init__.py)
import tattotronix  # noqa: F401

# isort: split
import logging

import numpy as np
from PIL import Image

from tattotronix.app.pipeline import check_reach
from tattotronix.app.records import save_mask
from tattotronix.art.artwork import artwork_grid, artwork_name, check_same_source
from tattotronix.art.mask import mask_on_panel
from tattotronix.config.schema import Config
from tattotronix.errors import TattotronixError
from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.stages.mask")


def main(cfg: Config, out: Outputs) -> None:
    """Threshold (or edge-detect) the artwork raster where it lies on the panel (refused off
    it, or out of the arm's reach); write the mask, preview and metrics."""
    name = artwork_name(cfg.artwork)
    src = out.require(out.input("artwork", f"{name}.png"), "artwork")
    try:
        with Image.open(src) as im:
            grey = np.asarray(im.convert("L"), dtype=np.float64)
    except (OSError, SyntaxError, ValueError, EOFError, MemoryError,
            Image.DecompressionBombError) as exc:  # truncated, corrupt, not a PNG, huge
        raise TattotronixError(
            f"cannot read {src} ({type(exc).__name__}: {' '.join(str(exc).split())}); "
            "re-run the 'artwork' stage"
        ) from None
    art_metrics = out.require(out.input("metrics", "artwork", f"{name}.json"), "artwork")
    check_same_source(art_metrics, cfg.artwork.source, name, replacing=False)
    grid = artwork_grid(art_metrics, grey.shape)
    mask, stats = mask_on_panel(grey, grid.res_mm, cfg.mask, cfg.robot.panel.size_mm,
                                grid.transparent)
    check_reach(cfg, mask)
    npz = save_mask(out, cfg, name, mask, src)
    preview = out.path("mask", f"{name}.png")
    Image.fromarray(np.where(mask.ink, 0, 255).astype(np.uint8), mode="L").save(
        out.tmp_path(preview), format="PNG"
    )
    out.write_json(out.path("metrics", "mask", f"{name}.json"), {"name": name, **stats.as_dict()})
    log.info("mask %s: %s", name, npz)


if __name__ == "__main__":
    run_stage("mask", main)
