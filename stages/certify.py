"""Stage `certify`: every figure in the documents traced to data; every local link resolves.

Reads README.md and docs/**/*.md from the project root (the current folder: DVC runs
stages from there), the metrics files under ``<paths.data>/metrics`` and params.yaml, and
the exemptions in docs/certify.yaml (see ``tattotronix.report.certify``). Writes
``<paths.data>/certify.json`` (beside the metrics folder it reads, not in it): the
counts (documents, figures, traced, exempted, links, sources; failures 0). Any failure
(a figure that traces to no number, a stale or reasonless exemption, a broken link, image
or anchor) stops the stage with the list, exit code 2, and nothing written.

A link to a file a stage produces (a figure under data/figures/) must exist: run this
stage after the pipeline (``dvc repro`` orders it so).
"""

from __future__ import annotations

import logging
from pathlib import Path

from tattotronix.config.schema import Config
from tattotronix.errors import TattotronixError
from tattotronix.io.outputs import Outputs
from tattotronix.report.certify import OUTPUT_NAME, certify
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.certify")


def main(cfg: Config, out: Outputs) -> None:
    """Certify the documents; write the counts, or fail with every problem found."""
    root = Path.cwd()
    report = certify(root, metrics_dir=root / out.path("metrics"))
    if not report.ok:
        raise TattotronixError(report.format())
    summary = report.summary()
    out.write_json(out.path(OUTPUT_NAME), summary)
    log.info("certify: %d document(s), %d figure(s): %d traced, %d exempted; %d local "
             "link(s) (%d external, not checked); %d source numbers (%d ignored)",
             summary["documents"], summary["figures"], summary["traced"],
             summary["exempted"], summary["links"], summary["external_links"],
             summary["sources"], summary["sources_ignored"])


if __name__ == "__main__":
    run_stage("certify", main)
