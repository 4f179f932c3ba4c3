"""Stage `timelaw`: one case of the time-law study (tattotronix/studies/timelaw.py).

    python stages/timelaw.py [overrides]   # one case, named from the swept keys
    python stages/timelaw.py -m KEY=a,b,c  # a sweep (in parallel: Hydra's joblib launcher)

Writes data/metrics/timelaw/<name>/<case>.json and data/studies/timelaw/<name>/<case>.npz.
"""

from tattotronix.stage import run_stage
from tattotronix.studies.timelaw import STUDY

if __name__ == "__main__":
    run_stage(STUDY.name, STUDY.stage_body)
