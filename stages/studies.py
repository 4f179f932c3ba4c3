"""Stage `studies`: the figure and the conclusions of every closed-loop study.

Reads the cases under data/metrics/<study>/<name>/ of every study in
tattotronix/studies/registry.py (the stages of those names: control, approach, resample,
rate) and writes data/figures/<name>/<study>.png, data/metrics/studies/<name>.json
(what each study concludes: the best structure and bandwidth, the shortest approach that
is enough, how many rate verdicts agree with the computed boundary) and each study's curve
for ``dvc plots``, data/plots/<name>/studies/<study>.csv.
"""

from __future__ import annotations

# first: a Ctrl-C while the libraries below import ends in one line (tattotronix/__init__.py)
import tattotronix  # noqa: F401

# isort: split
import logging

from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.errors import TattotronixError
from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage
from tattotronix.studies.registry import (
    STUDIES,
    format_summary,
    load_studies,
    study_curves,
    study_figures,
    study_summary,
)

log = logging.getLogger("tattotronix.studies")


def main(cfg: Config, out: Outputs) -> None:
    """Draw the study figures of the configured artwork; write the conclusions."""
    name = artwork_name(cfg.artwork)
    loaded = load_studies(out.data, name)
    if not loaded:
        *most, last = STUDIES
        raise TattotronixError(f"no study cases for '{name}' under {out.input('metrics')}: "
                               f"run the {', '.join(most)} and {last} stages first")
    written = study_figures(loaded, name, out.path("figures", name), out.tmp_path)
    summary = study_summary(loaded)
    out.write_json(out.path("metrics", "studies", f"{name}.json"), summary)
    for study, rows in study_curves(loaded).items():
        out.write_csv(out.path("plots", name, "studies", f"{study}.csv"), rows)
    log.info("studies %s: figures %s", name, ", ".join(written))
    for study, conclusions in summary.items():
        log.info("studies %s: %s: %s", name, study, format_summary(conclusions))


if __name__ == "__main__":
    run_stage("studies", main)
