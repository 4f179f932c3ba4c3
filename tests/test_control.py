"""The controller, the plants, the closed loop and its scoring (issue: control and plants)."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tattotronix.app.pipeline import plan_drawing
from tattotronix.config.params import compose_settings
from tattotronix.config.schema import PlantConfig, to_dict
from tattotronix.control.controller import Controller, Gains, structure_of
from tattotronix.control.dynamics import Dynamics
from tattotronix.control.ink import compare_ink, ink_grid, rasterise_ink
from tattotronix.control.reference import Reference, reference_at_ticks, resolve_window
from tattotronix.control.simulate import Loop, Run, simulate, substeps_per_tick
from tattotronix.control.tracking import busiest_window, entry_times, tracking_errors
from tattotronix.errors import TattotronixError
from tattotronix.kinematics import Chain
from tattotronix.plants import BACKENDS, PlantSettings, make_plant
from tattotronix.robot.description import RobotDescription
from tattotronix.trajectory import Trajectory

from .conftest import small_art

# the original's published tuning (docs/original.md, "5.3 Tuning by pole placement")
Q_REF_TUNE = np.array([-0.0112645418, 0.5611492471, 0.4417099134, -7.58e-9, 0.5679371434])
KP_20 = np.array([4.3224, 3.1959, 0.7526, 0.0218, 0.0362])
KI_20 = np.array([28.8158, 21.3063, 5.0172, 0.1456, 0.2414])
KD_20 = np.array([0.21612, 0.15980, 0.03763, 0.00109, 0.00181])


@pytest.fixture(scope="module")
def dyn(models: tuple[Path, Path], desc: RobotDescription) -> Dynamics:
    return Dynamics(models[0], desc.gravity)


@pytest.fixture(scope="module")
def small_drawing(tmp_path_factory: pytest.TempPathFactory, desc: RobotDescription
                  ) -> Trajectory:
    """The small artwork, 24 mm wide, planned in memory with the default settings."""
    art = small_art(tmp_path_factory.mktemp("art") / "small.png")
    cfg = compose_settings([f"artwork.source={art}", "mask.width_mm=24",
                            "mask.min_region_mm2=0.5"])
    return plan_drawing(cfg, art, "small", desc)


def make(backend: str, models: tuple[Path, Path], desc: RobotDescription, **kw: object):
    plant = replace(PlantConfig(), **kw)  # type: ignore[arg-type]
    settings = PlantSettings.from_settings(plant, desc.gravity, desc.tip_frame)
    return make_plant(backend, settings, urdf=models[0], mjcf=models[1],
                      joint_names=desc.joint_names, lower=desc.lower, upper=desc.upper)


# ----------------------------------------------------------------------------- gains


def test_gains_at_q_ref_tune_match_the_published_table(dyn: Dynamics) -> None:
    g = Gains.tuned_at(dyn, Q_REF_TUNE, 20.0)
    for got, want in ((g.kp, KP_20), (g.ki, KI_20), (g.kd, KD_20)):
        assert np.allclose(got, want, rtol=0.005), (got, want)
    g160 = Gains.tuned_at(dyn, Q_REF_TUNE, 160.0)
    assert np.allclose(g160.kp, 76_800 * g.j_eff) and np.allclose(g160.kd, 480 * g.j_eff)
    assert np.allclose(g160.ki, 4.096e6 * g.j_eff)


def test_bad_controller_settings_are_refused(dyn: Dynamics) -> None:
    g = Gains.tuned_at(dyn, Q_REF_TUNE, 20.0)
    with pytest.raises(TattotronixError, match="pid_g_v"):
        structure_of("pid_gv")
    with pytest.raises(TattotronixError, match="rate_hz"):
        Controller(dyn, g, "pid", 0.0, 20.0)
    with pytest.raises(TattotronixError, match="wn"):
        Gains.pole_placement(g.j_eff, -1.0, Q_REF_TUNE)
    with pytest.raises(TattotronixError, match="whole number"):
        substeps_per_tick(1 / 300, 1e-3)


def _one_tick_ref(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, period: float) -> Reference:
    return Reference(t=np.array([0.0, period]), q=np.stack([q, q]), qd=np.stack([qd, qd]),
                     qdd=np.stack([qdd, qdd]), period_s=period)


@pytest.mark.parametrize("structure", ["pid", "pid_g", "pid_g_v", "computed_torque"])
def test_controller_law_matches_section_5_2(dyn: Dynamics, structure: str) -> None:
    rng = np.random.default_rng(1)
    g = Gains.tuned_at(dyn, Q_REF_TUNE, 40.0)
    period = 1e-3
    qr, qdr, qddr = Q_REF_TUNE + 0.01, rng.normal(size=5) * 0.1, rng.normal(size=5)
    q, qd = Q_REF_TUNE.copy(), rng.normal(size=5) * 0.1
    c = Controller(dyn, g, structure, 1 / period, 20.0)
    c.bind(_one_tick_ref(qr, qdr, qddr, period))
    tau = np.array(c.torque(0, q, qd))
    e = qr - q
    integral = e * period  # updated with the new error before tau
    ed = (qdr - qd) if structure in ("pid_g_v", "computed_torque") else -qd
    want = g.kp * e + g.ki * integral + g.kd * ed
    if structure in ("pid_g", "pid_g_v"):
        want += dyn.gravity(q)
    if structure == "computed_torque":
        want += dyn.rnea(q, qd, qddr)  # M qdd_r + C qd + G
    assert np.allclose(tau, want, rtol=1e-12, atol=1e-12)
    assert np.allclose(c.integral, integral)


def test_torque_is_clamped_after_the_feedforward(dyn: Dynamics) -> None:
    g = Gains.tuned_at(dyn, Q_REF_TUNE, 160.0)
    c = Controller(dyn, g, "pid_g", 1000.0, 0.05)
    c.bind(_one_tick_ref(Q_REF_TUNE + 0.5, np.zeros(5), np.zeros(5), 1e-3))
    tau = np.array(c.torque(0, Q_REF_TUNE.copy(), np.zeros(5)))
    assert np.all(np.abs(tau) <= 0.05 + 1e-15) and np.any(np.abs(tau) == 0.05)


# ----------------------------------------------------------------------------- plants


@pytest.mark.parametrize("backend", BACKENDS)
def test_plants_report_the_same_tip_and_fall_alike(backend: str, models: tuple[Path, Path],
                                                   desc: RobotDescription,
                                                   dyn: Dynamics) -> None:
    """Reset, tip pose against the chain's FK, and 50 ms of free fall under zero torque
    (no velocity motors, no link damping) against the model plant's ABA."""
    chain = Chain.from_description(desc)
    q0 = np.array([0.2, 0.4, -0.6, 0.1, -0.8])
    with make(backend, models, desc) as plant:
        plant.reset(q0)
        pos, rot = plant.tip_pose()
        tip, axis = chain.fk(q0)
        assert np.allclose(pos, tip[0], atol=1e-7)
        assert np.allclose(rot[:, 2], axis[0], atol=1e-7)
        plant.apply([0.0] * 5)
        plant.step(50)
        q_fall = plant.q.copy()
    with make("model", models, desc) as ref:
        ref.reset(q0)
        ref.apply([0.0] * 5)
        ref.step(50)
        assert np.allclose(q_fall, ref.q, atol=1e-6), (q_fall - ref.q)
    assert np.abs(q_fall - q0).max() > 1e-3  # it did fall


@pytest.mark.parametrize("backend", BACKENDS)
def test_damping_is_off_unless_configured(backend: str, models: tuple[Path, Path],
                                          desc: RobotDescription) -> None:
    """A spinning base joint: undamped it moves as the model plant's undamped ABA (no
    hidden friction); with plant.damping it is slower."""
    def spin(name: str, damping: float) -> float:
        with make(name, models, desc, damping=damping) as plant:
            plant.reset(np.zeros(5), [1.0, 0, 0, 0, 0])
            plant.apply([0.0] * 5)
            plant.step(100)
            return float(plant.qd[0])

    free = spin("model", 0.0)
    assert spin(backend, 0.0) == pytest.approx(free, abs=1e-6)
    assert spin(backend, 0.01) < free - 0.05


def test_bad_plant_settings_are_refused(models: tuple[Path, Path],
                                        desc: RobotDescription) -> None:
    with pytest.raises(TattotronixError, match="contact"):
        make("model", models, desc, contacts=True)
    with pytest.raises(TattotronixError, match="unknown backend 'gazebo'"):
        make("gazebo", models, desc)


# ----------------------------------------------------------------------------- the loop


def _stretch(traj: Trajectory, length: float) -> tuple[float, float]:
    """A stretch that starts 0.5 s before the first needle entry."""
    start = max(0.0, float(entry_times(traj.t, traj.kind)[0]) - 0.5)
    return start, min(start + length, float(traj.t[-1]))


def _run(backend: str, traj: Trajectory, models: tuple[Path, Path], desc: RobotDescription,
         dyn: Dynamics, start: float, end: float, *, wn: float = 160.0, rate: float = 1000.0,
         dt: float = 1e-3, structure: str = "pid_g_v", loop: Loop = "auto",
         limit: float = 20.0):
    ref = reference_at_ticks(traj.t, traj.q, traj.qd, 1 / rate, start, end)
    c = Controller(dyn, Gains.tuned_at(dyn, ref.middle_pose(), wn), structure, rate, limit)
    with make(backend, models, desc, dt_s=dt) as plant:
        return simulate(plant, c, ref, sample_every=max(1, round(0.02 * rate)), loop=loop)


def test_three_plants_agree_on_a_3_s_stretch(small_drawing: Trajectory,
                                            models: tuple[Path, Path],
                                            desc: RobotDescription, dyn: Dynamics) -> None:
    start, end = _stretch(small_drawing, 3.0)
    chain = Chain.from_description(desc)
    settled, paths = {}, {}
    for backend in BACKENDS:
        run = _run(backend, small_drawing, models, desc, dyn, start, end)
        assert run.completed and run.verdict == "ok"
        idx = np.arange(0, len(run.t), run.sample_every)
        tip, _ = chain.fk(run.q[idx])
        tip_ref, _ = chain.fk(run.ref.q[idx])
        err = tracking_errors(run.t[idx], tip, tip_ref, small_drawing.t, small_drawing.kind,
                              160.0)
        m = err.metrics()
        assert err.entries >= 1 and m["settled_mean_um"] is not None
        settled[backend] = m["settled_mean_um"]
        paths[backend] = run.q
    lo, hi = min(settled.values()), max(settled.values())
    assert hi <= 1.2 * lo, settled
    for backend in BACKENDS:
        assert np.abs(paths[backend] - paths["model"]).max() < 1e-3


@pytest.mark.parametrize("backend", BACKENDS)
def test_past_the_sampled_boundary_is_caught(backend: str, small_drawing: Trajectory,
                                             models: tuple[Path, Path],
                                             desc: RobotDescription, dyn: Dynamics) -> None:
    """200 Hz at wn = 160 (wn T = 0.8, boundary ~0.3): saturated or diverged, finite."""
    start, end = _stretch(small_drawing, 3.0)
    run = _run(backend, small_drawing, models, desc, dyn, start, end, rate=200.0)
    assert run.verdict in ("saturated", "diverged")
    assert np.all(np.isfinite(run.q)) and np.all(np.isfinite(run.tau))
    assert math.isfinite(run.peak_torque_nm)


def test_defaults_inside_the_boundary_track_to_microns(small_drawing: Trajectory,
                                                       models: tuple[Path, Path],
                                                       desc: RobotDescription,
                                                       dyn: Dynamics) -> None:
    run = _run("mujoco", small_drawing, models, desc, dyn, 0.0, float(small_drawing.t[-1]))
    assert run.verdict == "ok" and run.completed
    chain = Chain.from_description(desc)
    tip, _ = chain.fk(run.q)
    tip_ref, _ = chain.fk(run.ref.q)
    assert np.linalg.norm(tip - tip_ref, axis=1).max() < 1e-3  # under a millimetre anywhere


# ------------------------------------------------------------- the loop inside the engine

#: how far the engine's PID may differ from the Python controller. Both compute the same
#: law in double precision, in another order: terms up to Kp |q_r| ~ 300 N m round at
#: ~7e-14 N m each, ~1e-13 N m a tick; on the lightest joint (J_eff 1.8e-5 kg m^2, 1 ms)
#: that moves a joint by < 1e-14 rad a tick, and the stable loop does not let it pile up
#: (measured on the whole emblem: 1.3e-15 rad, 1.5e-13 N m). The bounds leave 100x margin.
ENGINE_Q_TOL_RAD = 1e-12
ENGINE_TAU_TOL_NM = 1e-10


def _same_run(a: Run, b: Run) -> None:
    assert (a.loop, b.loop) == ("python", "engine")
    assert (a.verdict, a.reason, a.completed) == (b.verdict, b.reason, b.completed)
    assert len(a.t) == len(b.t) and a.qd_samples.shape == b.qd_samples.shape
    assert np.abs(a.q - b.q).max() < ENGINE_Q_TOL_RAD
    assert np.abs(a.qd_samples - b.qd_samples).max() < 1e3 * ENGINE_Q_TOL_RAD  # rad/s
    assert np.abs(a.tau - b.tau).max() < ENGINE_TAU_TOL_NM


@pytest.mark.parametrize("structure", ["pid", "pid_g", "pid_g_v"])
def test_the_engine_runs_the_same_controller_on_a_3_s_stretch(
        structure: str, small_drawing: Trajectory, models: tuple[Path, Path],
        desc: RobotDescription, dyn: Dynamics) -> None:
    start, end = _stretch(small_drawing, 3.0)
    runs = [_run("mujoco", small_drawing, models, desc, dyn, start, end, wn=40.0,
                 structure=structure, loop=loop) for loop in ("python", "engine")]
    _same_run(*runs)
    assert runs[1].summary()["loop_path"] == "engine"


def test_the_engine_runs_the_same_controller_over_a_whole_drawing(
        small_drawing: Trajectory, models: tuple[Path, Path], desc: RobotDescription,
        dyn: Dynamics) -> None:
    end = float(small_drawing.t[-1])
    runs = [_run("mujoco", small_drawing, models, desc, dyn, 0.0, end, loop=loop)
            for loop in ("python", "engine")]
    _same_run(*runs)
    assert runs[1].verdict == "ok" and runs[1].completed


def test_the_engine_clamps_gravity_and_pid_together(
        small_drawing: Trajectory, models: tuple[Path, Path], desc: RobotDescription,
        dyn: Dynamics) -> None:
    """A limit the run reaches: both paths clamp the sum, and agree."""
    start, end = _stretch(small_drawing, 1.0)
    runs = [_run("mujoco", small_drawing, models, desc, dyn, start, end, structure="pid_g",
                 limit=0.05, loop=loop) for loop in ("python", "engine")]
    assert np.abs(runs[1].tau).max() == pytest.approx(0.05)
    assert runs[1].verdict in ("saturated", "diverged")
    _same_run(*runs)


def test_the_engine_stops_a_diverging_run_where_the_python_loop_does(
        small_drawing: Trajectory, models: tuple[Path, Path], desc: RobotDescription,
        dyn: Dynamics) -> None:
    """wn 400 at 1 kHz (wn T 0.4, past the sampled boundary ~0.28): the same tick, the
    same reason; what ran before the blow-up agrees."""
    start, end = _stretch(small_drawing, 3.0)
    a, b = (_run("mujoco", small_drawing, models, desc, dyn, start, end, wn=400.0,
                 structure="pid_g", loop=loop) for loop in ("python", "engine"))
    assert a.verdict == b.verdict == "diverged" and a.reason == b.reason
    assert len(a.t) == len(b.t) < 3000
    assert np.all(np.isfinite(b.q)) and np.all(np.isfinite(b.tau))


def test_the_path_is_chosen_where_the_engine_can_run_the_controller(
        small_drawing: Trajectory, models: tuple[Path, Path], desc: RobotDescription,
        dyn: Dynamics) -> None:
    start, end = _stretch(small_drawing, 0.2)
    auto = {(backend, structure, dt): _run(backend, small_drawing, models, desc, dyn, start,
                                           end, structure=structure, dt=dt).loop
            for backend, structure, dt in (("mujoco", "pid_g_v", 1e-3),
                                           ("mujoco", "computed_torque", 1e-3),
                                           ("mujoco", "pid_g", 2.5e-4),
                                           ("pybullet", "pid_g_v", 1e-3),
                                           ("model", "pid", 1e-3))}
    assert auto == {("mujoco", "pid_g_v", 1e-3): "engine",
                    ("mujoco", "computed_torque", 1e-3): "python",
                    ("mujoco", "pid_g", 2.5e-4): "python",
                    ("pybullet", "pid_g_v", 1e-3): "python",
                    ("model", "pid", 1e-3): "python"}
    for backend, structure, dt, why in (
            ("mujoco", "computed_torque", 1e-3, "no engine form"),
            ("mujoco", "pid_g", 2.5e-4, "slower than the plant"),
            ("pybullet", "pid_g", 1e-3, "no native PID")):
        with pytest.raises(TattotronixError, match=why):
            _run(backend, small_drawing, models, desc, dyn, start, end, structure=structure,
                 dt=dt, loop="engine")
    with pytest.raises(TattotronixError, match="loop='fast'"):
        _run("mujoco", small_drawing, models, desc, dyn, start, end,
             loop="fast")  # type: ignore[arg-type]


# ----------------------------------------------------------------------------- scoring


def test_tracking_errors_follow_section_5_5() -> None:
    """Down from marking segments (interpolated between point times, > 0.5); entries are
    rising edges; settled drops 4/wn after each."""
    t_pts = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    kind = np.array([0, 2, 1, 1, 0, 1, 1], dtype=np.int8)  # marks 2-3 and 5-6
    t = np.arange(0.0, 6.0, 0.02)
    err = np.where(t < 4.0, 10e-6, 20e-6)
    tip_ref = np.zeros((len(t), 3))
    tip = tip_ref + np.stack([err, 0 * err, 0 * err], axis=1)
    e = tracking_errors(t, tip, tip_ref, t_pts, kind, wn=10.0)  # settle 0.4 s
    m = e.metrics()
    assert e.entries == 2
    # m = (0, 0, 1, 0, 0, 1) at t = 0..5: above 0.5 on (1.5, 2.5) and after 4.5
    down = ((t > 1.5 + 1e-9) & (t < 2.5 - 1e-9)) | (t > 4.5 + 1e-9)
    assert np.array_equal(e.down, down)
    first = t[down][0]  # 1.52: the entry; settled from 1.92
    assert not e.settled[(t >= first) & (t < first + 0.4 - 1e-9)].any()
    assert e.settled[(t >= first + 0.4 + 1e-9) & (t < 2.5 - 1e-9)].all()
    assert m["marking_max_um"] == pytest.approx(20.0) and m["travel_mean_um"] is not None
    assert entry_times(t_pts, kind).tolist() == [2.0, 5.0]


def test_busiest_window_starts_at_the_entry_with_most_entries_ahead() -> None:
    t_pts = np.arange(0.0, 100.0, 1.0)
    kind = np.zeros(100, dtype=np.int8)
    for s in (5, 40, 43, 46, 49, 70):  # 2-point marks with a travel point between
        kind[s:s + 2] = 1
    start, length = busiest_window(t_pts, kind, 12.0)
    assert (start, length) == (40.0, 12.0)


def test_window_parsing() -> None:
    t = np.linspace(0.0, 10.0, 11)
    kind = np.ones(11, dtype=np.int8)
    assert resolve_window(None, t, kind) == (0.0, 10.0)
    assert resolve_window([2, 3], t, kind) == (2.0, 5.0)
    assert resolve_window([8, 30], t, kind) == (8.0, 10.0)
    assert resolve_window([4], t, kind) == (4.0, 10.0)
    for bad in ([11, 1], [2, -1], "middle", [1, 2, 3], ["a", 1]):
        with pytest.raises(TattotronixError, match="window"):
            resolve_window(bad, t, kind)


def _line(x0: float, x1: float, y: float, depth: float = -0.5e-3) -> np.ndarray:
    x = np.linspace(x0, x1, 200)
    return np.stack([x, np.full_like(x, y), np.full_like(x, depth)], axis=1)


def test_ink_is_the_needle_width_and_only_below_the_surface() -> None:
    origin = np.zeros(3)
    line = _line(0.0, 0.01, 0.0)
    above = _line(0.0, 0.01, 0.002, depth=0.1e-3)
    grid = ink_grid([line], origin, 0.02)
    ink = rasterise_ink(np.concatenate([line, above]), origin, grid, 0.3)
    width_px = ink[:, ink.shape[1] // 2].sum()
    assert abs(width_px * 0.02 - 0.3) <= 0.02 + 1e-9  # within a pixel
    assert ink.sum() * 0.02**2 == pytest.approx(10.0 * 0.3, rel=0.06)  # 10 mm x 0.3 mm


def test_ink_comparison_iou_and_worst_deviation() -> None:
    origin = np.zeros(3)
    a = _line(0.0, 0.01, 0.0)
    b = _line(0.0, 0.01, 0.2e-3)  # 0.2 mm off
    grid = ink_grid([a, b], origin, 0.02)
    ia, ib = (rasterise_ink(p, origin, grid, 0.3) for p in (a, b))
    same = compare_ink(ia, ia, 0.02)
    assert same.iou == 1.0 and same.max_dev_mm == 0.0
    off = compare_ink(ia, ib, 0.02)
    assert off.iou == pytest.approx(0.1 / 0.5, abs=0.04)  # overlap 0.1 of a 0.5 mm union
    assert off.max_dev_mm == pytest.approx(0.2, abs=0.03)
    empty = compare_ink(np.zeros_like(ia), ia, 0.02)
    # no ink: no distance to give (null with the reason, never inf nor a perfect 0)
    assert empty.iou == 0.0 and empty.metrics()["ink_max_dev_mm"] is None
    assert empty.metrics()["ink_reason"] == "no worst deviation: the run inked nothing"


def test_run_metrics_never_hold_nan(tmp_path: Path) -> None:
    from tattotronix.control.drawing import _finite

    out = _finite({"a": float("nan"), "b": [1.0, float("inf")], "c": np.float64(2.0)})
    assert json.loads(json.dumps(out)) == {"a": None, "b": [1.0, None], "c": 2.0}


def test_config_has_the_draw_defaults() -> None:
    cfg = compose_settings()
    assert cfg.controller.wn == 160.0 and cfg.controller.rate_hz == 1000.0
    assert cfg.controller.structure.name == "pid_g_v"
    assert cfg.backend.name == "mujoco" and cfg.plant.damping == 0.0


# ----------------------------------------------------------------------------- what is played


def test_stored_drawing_is_played_as_is_and_retimed_for_another_speed(
        tmp_path: Path, small_drawing: Trajectory, desc: RobotDescription) -> None:
    from tattotronix.app.drawings import resolve_drawing
    from tattotronix.io.provenance import provenance_json

    cfg = compose_settings(["art=small"])
    (tmp_path / "trajectories").mkdir()
    (tmp_path / "ik").mkdir()
    config = to_dict(cfg)
    small_drawing.save(tmp_path / "trajectories" / "small.npz",
                           provenance_json({str(k): v for k, v in config.items()}, {}, "test"))
    tr = small_drawing
    ik = tr.source >= 0  # the IK path's own points (not densified, not planned travel)
    np.savez(tmp_path / "ik" / "small.npz", joints=np.array(tr.joints), q=tr.q[ik],
             tcp=tr.tcp[ik], kind=tr.kind[ik], uvz_mm=tr.uvz_mm[ik], xyz_m=tr.tcp[ik],
             stroke=np.zeros(int(ik.sum())), residual=np.zeros(int(ik.sum())),
             provenance=np.array("{}"))
    same = resolve_drawing(cfg, tmp_path, desc)
    assert same.origin == "stored" and np.array_equal(same.q, tr.q)
    fast = resolve_drawing(compose_settings(["art=small", "speed=2"]), tmp_path, desc)
    assert fast.origin == "retimed" and fast.t[-1] < 0.75 * tr.t[-1]
    with pytest.raises(TattotronixError, match="available are small, emblem, portrait"):
        resolve_drawing(compose_settings(["art=other"]), tmp_path, desc)


def test_every_simulated_backend_of_the_config_has_a_plant() -> None:
    """``backend=`` is checked by the config schema; the factory builds each of those
    (all but the real arm, and the servo plant, which plays the servo program rather than
    torques: tattotronix.app.servos), and nothing else."""
    from tattotronix.config.schema import Backend

    assert set(BACKENDS) == {b.value for b in Backend} - {"arm", "servo"}
