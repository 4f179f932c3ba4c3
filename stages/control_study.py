"""Stage `control`: one case of the control study (tattotronix/studies/control.py).

    python stages/control_study.py [overrides]   # one case, named from the swept keys
    python stages/control_study.py -m KEY=a,b,c  # a sweep (in parallel: Hydra's joblib launcher)

Writes data/metrics/control/<name>/<case>.json and data/studies/control/<name>/<case>.npz.
"""

from tattotronix.stage import run_stage
from tattotronix.studies.control import STUDY

if __name__ == "__main__":
    run_stage(STUDY.name, STUDY.stage_body)
