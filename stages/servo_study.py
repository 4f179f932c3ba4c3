"""Stage `servo`: one case of the servo study (tattotronix/studies/servo.py).

    python stages/servo_study.py [overrides]   # one case, named from the swept keys
    python stages/servo_study.py -m servo.type=SG90,STS3215   # a sweep (Hydra's joblib)

Every case plays the whole drawing on the servo plant (backend=servo). Writes
data/metrics/servo/<name>/<case>.json and data/studies/servo/<name>/<case>.npz.
"""

from tattotronix.stage import run_stage
from tattotronix.studies.servo import STUDY

if __name__ == "__main__":
    run_stage(STUDY.name, STUDY.stage_body)
