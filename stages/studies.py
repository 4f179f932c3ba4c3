"""Stage `studies`: the figure and the conclusions of every closed-loop study.

Reads the cases under data/metrics/{control,approach,resample,rate}/<name>/ (the stages
of those names) and writes data/figures/<name>/{control,approach,resample,rate}.png and
data/metrics/studies/<name>.json (what each study concludes: the best structure and
bandwidth, the shortest approach that is enough, how many rate verdicts agree with the
computed boundary).
"""

from __future__ import annotations

import logging

from omegaconf import DictConfig

from tattotronix.art.artwork import artwork_name
from tattotronix.errors import TattotronixError
from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage
from tattotronix.studies.figures import study_figures, study_summary

log = logging.getLogger("tattotronix.studies")


def main(cfg: DictConfig, out: Outputs) -> None:
    """Draw the study figures of the configured artwork; write the conclusions."""
    name = artwork_name(cfg.artwork)
    written = study_figures(out.data, name, out.path("figures", name), out.tmp_path)
    if not written:
        raise TattotronixError(f"no study cases for '{name}' under {out.path('metrics')}: "
                               "run the control, approach, resample and rate stages first")
    summary = study_summary(out.data, name)
    out.write_json(out.path("metrics", "studies", f"{name}.json"), summary)
    log.info("studies %s: figures %s; %s", name, ", ".join(written), summary)


if __name__ == "__main__":
    run_stage("studies", main)
