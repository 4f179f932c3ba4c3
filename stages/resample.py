"""Stage `resample`: one case of the resample study (tattotronix/studies/resample.py).

    python stages/resample.py [overrides]   # one case, named from the swept keys
    python stages/resample.py -m KEY=a,b,c  # a sweep (in parallel: Hydra's joblib launcher)

Writes data/metrics/resample/<name>/<case>.json and data/studies/resample/<name>/<case>.npz.
"""

from tattotronix.stage import run_stage
from tattotronix.studies.resample import STUDY

if __name__ == "__main__":
    run_stage(STUDY.name, STUDY.stage_body)
