"""Stage ``robustness``: what each servo correction still buys when the servos differ from
the catalogue (docs/servos.md, "Robustness"; tattotronix/studies/robustness.py).

    python stages/robustness.py [study.robustness.draws=N] [study.robustness.spread.backlash_pct=P]

Plays ``study.robustness.draws`` arms, drawn within ``study.robustness.spread`` of the
catalogue, over the study artwork's busiest window on the servo plant, with no correction,
each alone and all; writes ``data/metrics/robustness/<name>.json`` and the figure
``data/figures/<name>/robustness.png`` (drawn from those metrics).
"""

from __future__ import annotations

import logging

from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage
from tattotronix.studies.robustness import robustness_figure, run_robustness

log = logging.getLogger("tattotronix.stages.robustness")


def main(cfg: Config, out: Outputs) -> None:
    """Run the study; write its metrics and its figure."""
    name = artwork_name(cfg.artwork)
    metrics = run_robustness(cfg, out.data)
    out.write_json(out.path("metrics", "robustness", f"{name}.json"), metrics)
    robustness_figure(metrics, out.tmp_path(out.path("figures", name, "robustness.png")))
    conditions = metrics["conditions"]
    assert isinstance(conditions, dict)
    for c, m in conditions.items():
        assert isinstance(m, dict) and isinstance(m["mean_mm"], dict)
        log.info("robustness %s: %-9s mean marking deviation %s mm (median of %s arms; "
                 "catalogue %s mm)", name, c, m["mean_mm"].get("p50"),
                 m["mean_mm"].get("scored"), m["catalogue_mean_mm"])


if __name__ == "__main__":
    run_stage("robustness", main)
