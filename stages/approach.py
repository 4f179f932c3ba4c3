"""Stage `approach`: one case of the approach study (see :mod:`tattotronix.studies.sweeps`).

    python stages/approach.py [overrides]          # one case, named from the swept keys
    python stages/approach.py -m KEY=a,b,c         # a sweep (in parallel: Hydra's joblib launcher)

Writes data/metrics/approach/<name>/<case>.json and data/studies/approach/<name>/<case>.npz.
"""

from __future__ import annotations

from omegaconf import DictConfig

from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage
from tattotronix.studies.sweeps import run_case


def main(cfg: DictConfig, out: Outputs) -> None:
    """Run the case the config describes."""
    run_case("approach", cfg, out)


if __name__ == "__main__":
    run_stage("approach", main)
