"""Control: the whole built-in drawing in closed loop on every plant and path, and its
accuracy.

Needs the stored trajectory (``dvc repro`` makes ``data/trajectories/emblem.npz``).
The timed call is :func:`tattotronix.control.simulate.simulate`: the default controller
(pid_g_v, wn 160 rad/s, 1 kHz), the plant, the per-tick logging and the health checks;
scoring and ink come after and are not timed (reported separately). Each plant runs on
each path it has: MuJoCo inside the engine (its native PID stepped by
``mujoco.rollout``) and in the Python loop (gravity from Pinocchio every tick), PyBullet
and the model plant in the Python loop. Baselines measured in the same run: raw
``mj_step`` with zero torque (the engine alone) and a bare loop calling Pinocchio gravity
and ``mj_step``. Targets (issue 17, one core): the engine path 300x real time or more,
PyBullet 60x or more; marking_max_um below 20 over the whole drawing at the defaults (the
original: 46.8 on a 12 s window).
"""

from __future__ import annotations

import math
import statistics
import time
from pathlib import Path

import numpy as np
from run import Row

from tattotronix.config.params import compose_settings
from tattotronix.config.schema import PlantConfig
from tattotronix.control.controller import Controller, Gains
from tattotronix.control.dynamics import Dynamics
from tattotronix.control.reference import reference_at_ticks
from tattotronix.control.simulate import Loop, simulate
from tattotronix.control.tracking import tracking_errors
from tattotronix.io.artifacts import TrajectoryRecord
from tattotronix.kinematics import Chain
from tattotronix.plants import BACKENDS, PlantSettings, make_plant
from tattotronix.robot.description import build_description

DATA = Path(__file__).resolve().parents[1] / "data"


def _baselines(mjcf: Path, urdf: Path, q0: np.ndarray, steps: int, repeat: int,
               gravity: float) -> tuple[float, float]:
    """Seconds per step: raw ``mj_step``, and ``mj_step`` with Pinocchio gravity."""
    import mujoco
    import pinocchio as pin

    m = mujoco.MjModel.from_xml_path(str(mjcf))
    m.opt.disableflags |= (mujoco.mjtDisableBit.mjDSBL_CONTACT
                           | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    d = mujoco.MjData(m)
    pm = pin.buildModelFromUrdf(str(urdf))
    pm.gravity.linear = np.array([0.0, 0.0, -gravity])
    pd = pm.createData()
    chunk = 1000  # restart from q0 every second: a free arm would fall over for good
    raw, bare = [], []
    for _ in range(repeat):
        wall = [0.0, 0.0]
        for _ in range(steps // chunk):
            for i, gravity_ff in enumerate((False, True)):
                mujoco.mj_resetData(m, d)
                d.qpos[:] = q0
                t0 = time.perf_counter()
                if gravity_ff:
                    for _ in range(chunk):
                        d.ctrl[:] = pin.computeGeneralizedGravity(pm, pd, d.qpos)
                        mujoco.mj_step(m, d)
                else:
                    for _ in range(chunk):
                        mujoco.mj_step(m, d)
                wall[i] += time.perf_counter() - t0
        raw.append(wall[0] / steps)
        bare.append(wall[1] / steps)
    return statistics.median(raw), statistics.median(bare)


def bench(repeat: int) -> list[Row]:
    cfg = compose_settings()
    desc = build_description(cfg.robot)
    urdf = DATA / "robot" / f"{desc.name}.urdf"
    mjcf = DATA / "robot" / f"{desc.name}.xml"
    src = TrajectoryRecord.path(DATA, name="emblem")
    if not src.exists():
        return [("whole drawing", float("nan"), "x", f"{src} missing: run dvc repro first")]
    tr = TrajectoryRecord.load(src)
    dyn = Dynamics(urdf, desc.gravity)
    ref = reference_at_ticks(tr.t, tr.q, tr.qd, 1e-3)
    gains = Gains.tuned_at(dyn, ref.middle_pose(), 160.0)
    chain = Chain.from_description(desc)
    settings = PlantSettings.from_settings(PlantConfig(), desc.gravity, desc.tip_frame)
    reps = max(1, min(repeat, 3))  # each run is the whole ~10 min drawing
    rows: list[Row] = []
    rtf: dict[str, float] = {}
    runs: list[tuple[str, Loop]] = [("mujoco", "engine"), ("mujoco", "python"),
                                    ("pybullet", "python"), ("model", "python")]
    assert {b for b, _ in runs} == set(BACKENDS)
    target = {("mujoco", "engine"): " (target 300x)", ("pybullet", "python"): " (target 60x)"}
    for backend, path in runs:
        walls, run = [], None
        for _ in range(reps):
            ctl = Controller(dyn, gains, "pid_g_v", 1000.0, 20.0)
            with make_plant(backend, settings, urdf=urdf, mjcf=mjcf,
                            joint_names=desc.joint_names, lower=desc.lower,
                            upper=desc.upper) as plant:
                run = simulate(plant, ctl, ref, sample_every=20, loop=path)
            walls.append(run.wall_s)
        assert run is not None and run.loop == path
        wall = statistics.median(walls)
        key = f"{backend}, {path} loop"
        rtf[key] = run.sim_s / wall
        rows.append((f"real-time factor [{key}]", rtf[key], "x",
                     f"{run.sim_s:.0f} s simulated in {wall:.2f} s (median of {reps}), "
                     f"{wall / len(run.t) * 1e6:.2f} us per tick"
                     f"{target.get((backend, path), '')}"))
        if (backend, path) == ("mujoco", "engine"):
            t0 = time.perf_counter()
            idx = np.arange(0, len(run.t), run.sample_every)
            tip, _ = chain.fk(run.q[idx])
            tip_ref, _ = chain.fk(run.ref.q[idx])
            err = tracking_errors(run.t[idx], tip, tip_ref, tr.t, tr.kind, 160.0).metrics()
            score_s = time.perf_counter() - t0
            worst = err["marking_max_um"]
            rows.append(("marking_max_um [mujoco, defaults]",
                         float(worst) if isinstance(worst, int | float) else math.nan, "um",
                         f"settled mean {err['settled_mean_um']:.2f} um, max "
                         f"{err['settled_max_um']:.1f} um at {err['marking_worst_at_s']:.2f} s; "
                         f"target < 20, original 46.8 on 12 s; scoring {score_s:.2f} s"))
    rows.append(("engine path over the Python loop [mujoco]",
                 rtf["mujoco, engine loop"] / rtf["mujoco, python loop"], "ratio",
                 "the same controller, measured in this run"))
    raw, bare = _baselines(mjcf, urdf, ref.q[0], 100_000, reps, desc.gravity)
    dt = settings.dt_s
    rows.append(("raw mj_step (zero torque)", dt / raw, "x",
                 f"{raw * 1e6:.2f} us per step: the engine alone"))
    rows.append(("bare loop: Pinocchio gravity + mj_step", dt / bare, "x",
                 f"{bare * 1e6:.2f} us per step; the Python loop runs at "
                 f"{rtf['mujoco, python loop'] / (dt / bare):.2f} of this, the engine path "
                 f"at {rtf['mujoco, engine loop'] / (dt / raw):.2f} of raw mj_step"))
    return rows
