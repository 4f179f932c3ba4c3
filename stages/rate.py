"""Stage `rate`: one case of the rate study (see :mod:`tattotronix.studies.sweeps`).

    python stages/rate.py [overrides]          # one case, named from the swept keys
    python stages/rate.py -m KEY=a,b,c         # a sweep (in parallel: Hydra's joblib launcher)

Writes data/metrics/rate/<name>/<case>.json and data/studies/rate/<name>/<case>.npz.
"""

from __future__ import annotations

from omegaconf import DictConfig

from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage
from tattotronix.studies.sweeps import run_case


def main(cfg: DictConfig, out: Outputs) -> None:
    """Run the case the config describes."""
    run_case("rate", cfg, out)


if __name__ == "__main__":
    run_stage("rate", main)
