"""Stage `headline`: the headline figures of every drawing (README, "Metrics and
experiments"; ``tattotronix.report.headline``).

Reads, under ``<paths.data>/metrics``, ``trajectory/<name>.json`` and
``runs/<name>-mujoco.json`` of every drawing with a trajectory ('trajectory' and
'simulate' stages) and ``servo/<study artwork>/built.json`` ('servo' stage). Writes
``metrics/headline.json`` (the study artwork's figures, ``artwork.name``: the one DVC
metric, what ``dvc metrics show`` and ``dvc exp show`` show) and
``metrics/headline/<figure>.json`` (one figure of every drawing).
"""

from __future__ import annotations

import logging

from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.io.outputs import Outputs
from tattotronix.report.headline import format_headline, write_headline
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.headline")


def main(cfg: Config, out: Outputs) -> None:
    """Write the headline figures; log the study artwork's in one line."""
    name = artwork_name(cfg.artwork)
    log.info("headline %s", format_headline(name, write_headline(out, name)))


if __name__ == "__main__":
    run_stage("headline", main)
