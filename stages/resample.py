"""Stage `resample`: one case of the resample study (see :mod:`tattotronix.studies.sweeps`).

    python stages/resample.py [overrides]          # one case, named from the swept keys
    python stages/resample.py -m KEY=a,b,c         # a sweep (in parallel: Hydra's joblib launcher)

Writes data/metrics/resample/<name>/<case>.json and data/studies/resample/<name>/<case>.npz.
"""

from __future__ import annotations

from omegaconf import DictConfig

from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage
from tattotronix.studies.sweeps import run_case


def main(cfg: DictConfig, out: Outputs) -> None:
    """Run the case the config describes."""
    run_case("resample", cfg, out)


if __name__ == "__main__":
    run_stage("resample", main)
