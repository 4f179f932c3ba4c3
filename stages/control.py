"""Stage `control`: one case of the control study (see :mod:`tattotronix.studies.sweeps`).

This file shares python-control's package name; importing :mod:`tattotronix` takes
``stages/`` off the import path (``tattotronix/__init__.py``).

    python stages/control.py [overrides]          # one case, named from the swept keys
    python stages/control.py -m KEY=a,b,c         # a sweep (in parallel: Hydra's joblib launcher)

Writes data/metrics/control/<name>/<case>.json and data/studies/control/<name>/<case>.npz.
"""

from __future__ import annotations

from omegaconf import DictConfig

from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage
from tattotronix.studies.sweeps import run_case


def main(cfg: DictConfig, out: Outputs) -> None:
    """Run the case the config describes."""
    run_case("control", cfg, out)


if __name__ == "__main__":
    run_stage("control", main)
