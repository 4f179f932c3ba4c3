"""Stage `rate`: one case of the rate study (tattotronix/studies/rate.py).

    python stages/rate.py [overrides]   # one case, named from the swept keys
    python stages/rate.py -m KEY=a,b,c  # a sweep (in parallel: Hydra's joblib launcher)

Writes data/metrics/rate/<name>/<case>.json and data/studies/rate/<name>/<case>.npz.
"""

from tattotronix.stage import run_stage
from tattotronix.studies.rate import STUDY

if __name__ == "__main__":
    run_stage(STUDY.name, STUDY.stage_body)
