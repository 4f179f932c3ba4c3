"""Whole-path IK: the batched solver against the warm-started per-point Pinocchio loop.

On a synthetic logo-like path (nine filled dots and two rings over the 150 mm centred
drawing area, 0.15 mm steps, a lift between strokes: about 16 000 points), and on the
built-in artwork's toolpath when the toolpath stage has made it (``data/toolpath/*.npz``).
The ratio is against the per-point loop measured in the same run.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from run import Row, median_time

from tattotronix.config.params import compose_settings
from tattotronix.io.artifacts import TOOLPATH, ToolpathRecord
from tattotronix.kinematics import (
    Chain,
    PinocchioTip,
    solve_path,
    solve_path_sequential,
    verify,
)
from tattotronix.kinematics.synthetic import logo_like_strokes, stroke_path
from tattotronix.robot.description import build_description

DATA = Path(__file__).resolve().parents[1] / "data"


def _rows(label: str, chain: Chain, ref: PinocchioTip, x: np.ndarray,
          repeat: int) -> list[Row]:
    n = len(x)
    t, res = median_time(lambda: solve_path(chain, x), repeat)
    check = verify(ref, res, x)
    t_seq, seq = median_time(lambda: solve_path_sequential(ref, x), min(repeat, 3))
    same = float(np.abs(res.q - seq.q).max()) if seq.ok and res.ok else float("nan")
    return [
        (f"solve_path [{label}]", t, "s",
         f"{n} points, {res.converged_pct:.1f} % converged, worst residual "
         f"{res.worst_residual:.3g}, {res.stats.get('anchors', 0)} anchors, "
         f"{res.iterations.mean():.2f} iterations/point"),
        (f"points per second [{label}]", n / t, "points/s", "target >= 50 000 (0.3 s / 16k)"),
        (f"per-point Pinocchio loop [{label}]", t_seq, "s",
         f"warm-started, {seq.converged_pct:.1f} % converged, "
         f"{seq.iterations.mean():.2f} iterations/point"),
        (f"speed-up over the loop [{label}]", t_seq / t, "x",
         f"max |q - q_loop| {same:.2g} rad"),
        (f"converged [{label}]", res.converged_pct, "%",
         f"Pinocchio FK check: {check.max_position_error_m:.2g} m, "
         f"{check.max_axis_error_rad:.2g} rad"),
    ]


def bench(repeat: int) -> list[Row]:
    desc = build_description(compose_settings().robot)
    chain = Chain.from_description(desc)
    ref = PinocchioTip.from_description(desc)
    rows = _rows("16k synthetic", chain, ref, stroke_path(logo_like_strokes()).xyz_m, repeat)
    for npz in TOOLPATH.find(DATA)[:1]:
        x = np.asarray(ToolpathRecord.load(npz).xyz_m, dtype=float)
        rows += _rows(npz.stem, chain, ref, x, repeat)
    return rows
