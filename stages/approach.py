"""Stage `approach`: one case of the approach study (tattotronix/studies/approach.py).

    python stages/approach.py [overrides]   # one case, named from the swept keys
    python stages/approach.py -m KEY=a,b,c  # a sweep (in parallel: Hydra's joblib launcher)

Writes data/metrics/approach/<name>/<case>.json and data/studies/approach/<name>/<case>.npz.
"""

from tattotronix.stage import run_stage
from tattotronix.studies.approach import STUDY

if __name__ == "__main__":
    run_stage(STUDY.name, STUDY.stage_body)
