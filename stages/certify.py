"""Stage `certify`: every figure in the documents traced to data; every local link resolves.

Reads README.md and docs/**/*.md from the project root (the current folder: DVC runs
stages from there), the metrics files under ``<paths.data>/metrics`` and params.yaml, and
the exemptions in docs/certify.yaml (see ``tattotronix.devtools.certify``). Writes
``<paths.data>/certify.json`` (beside the metrics folder it reads, not in it; git-tracked,
not a DVC metric: ``dvc metrics show data/certify.json``): the counts (documents, figures,
traced, exempted, links, sources, failures).

On a branch, any failure (a figure that traces to no number, a reasonless exemption, a
broken link, image or anchor) stops the stage with the list, exit code 2, and nothing
written: ``main`` never carries a document that disagrees with its metrics. Inside a DVC
experiment (``dvc exp run``, which sets ``DVC_EXP_BASELINE_REV``) an experiment exists to
change the numbers, so the documents' drift is recorded instead: ``failures`` counts it
and ``drift`` lists it in certify.json (``dvc metrics show data/certify.json``), the log
says so in a few short lines (a count per document and the first figures), and the
experiment is saved.

A link to a file a stage produces (a figure under data/figures/) must exist: run this
stage after the pipeline (``dvc repro`` orders it so).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from tattotronix.config.schema import Config
from tattotronix.devtools.certify import EXPERIMENT_ENV, OUTPUT_NAME, certify
from tattotronix.errors import TattotronixError
from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.certify")


def main(cfg: Config, out: Outputs) -> None:
    """Certify the documents; write the counts, or fail with every problem found."""
    root = Path.cwd()
    report = certify(root, metrics_dir=root / out.input("metrics"))
    experiment = bool(os.environ.get(EXPERIMENT_ENV))
    if not report.ok and not experiment:
        raise TattotronixError(report.format())
    summary = report.summary()
    if not report.ok:
        # a few short lines: the whole list is certify.json's `drift`
        summary["drift"] = [str(f) for f in report.failures]
        log.warning("certify: inside a DVC experiment the documents' drift is recorded, "
                    "not enforced (the list: %s, drift):\n%s", out.path(OUTPUT_NAME),
                    report.drift_summary())
    if experiment and report.notes:
        log.info("certify: %d note(s) on exemptions (run certify on the branch to list "
                 "them)", len(report.notes))
    else:
        for note in report.notes:
            log.info("certify: note: %s", note)
    out.write_json(out.path(OUTPUT_NAME), summary)
    log.info("certify: %d document(s), %d figure(s): %d traced, %d exempted; %d local "
             "link(s) (%d external, not checked); %d source numbers (%d ignored)",
             summary["documents"], summary["figures"], summary["traced"],
             summary["exempted"], summary["links"], summary["external_links"],
             summary["sources"], summary["sources_ignored"])


if __name__ == "__main__":
    run_stage("certify", main)
