"""Stage `draw` (and DVC's `simulate`): play a drawing on a plant, closed loop.

    python stages/draw.py backend=mujoco|pybullet|model|servo art=NAME [speed=S]
        [controller.wn=160 controller.rate_hz=1000 controller.structure=pid_g_v]
        [window=[start_s,length_s] | window=busiest] [viewer=true]
    python stages/draw.py artwork.source=PATH ...     # plans the drawing first, in memory
    python stages/draw.py backend=arm art=NAME [dry_run=true [realtime=false]] [resume=true]

Writes runs/<name>-<backend>/{log.npz, ink.png, ink_vs_plan.png} and
metrics/runs/<name>-<backend>.json (tracking errors as the original defined them,
docs/original.md, "5.5 Tracking error"; peak torque, real-time factor, ink IoU against
the plan; the verdict against the drawing's tolerance, docs/control.md, "Verdicts", with a
WARNING: line when it is not ok) under data/ when DVC runs it (the simulate stage), under
runs/ by hand (README, "Hand runs"). On the arm: the plan first (preview=true stops there), then
runs/<name>-arm/{i2c.jsonl (dry run), poses.jsonl} and the arm state file.
"""

from __future__ import annotations

from tattotronix.app.draw import draw
from tattotronix.config.schema import Config
from tattotronix.io.outputs import Outputs
from tattotronix.stage import run_stage


def main(cfg: Config, out: Outputs) -> None:
    """Draw on the configured backend (:func:`tattotronix.app.draw.draw`)."""
    draw(cfg, out)


if __name__ == "__main__":
    run_stage("draw", main)
