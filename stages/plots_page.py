"""Stage `plots_page`: the page ``dvc plots show`` fills, with Vega, Vega-Lite and
Vega-Embed inlined, so the plots render offline (``tattotronix.report.plotpage``).

Reads nothing but the installed ``vl-convert-python``. Writes ``<paths.data>/plots/page.html``
(``.dvc/config``: ``plots.html_template``).
"""

from __future__ import annotations

import logging

from tattotronix.config.schema import Config
from tattotronix.io.outputs import Outputs
from tattotronix.report.plotpage import page_html
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.plots_page")


def main(cfg: Config, out: Outputs) -> None:
    """Write the page."""
    page = out.write_text(out.path("plots", "page.html"), page_html())
    log.info("plots_page: %s, Vega inlined (dvc plots show renders offline)", page)


if __name__ == "__main__":
    run_stage("plots_page", main)
