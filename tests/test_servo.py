"""The servo plant (``backend=servo``; docs/servos.md): the servo model's dead band, speed
limit, backlash and latency, the measured pulse-map fit, the ideal servo against the MuJoCo
plant, and what each correction (``hardware.compensate``) buys."""

from __future__ import annotations

import copy
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tattotronix.app.drawings import resolve_drawing
from tattotronix.app.servos import run_servo_loop
from tattotronix.app.simulate import run_closed_loop
from tattotronix.config.params import compose_settings
from tattotronix.config.schema import Config
from tattotronix.control.drawing import ClosedLoop, Drawing, score_ink
from tattotronix.control.ink import compare_ink
from tattotronix.errors import TattotronixError
from tattotronix.hardware.servo_model import joint_servos, measure_fit
from tattotronix.hardware.servos import (
    Calibration,
    CalibrationError,
    default_calibration,
    default_calibration_mapping,
)
from tattotronix.kinematics import Chain
from tattotronix.plants.base import PlantSettings
from tattotronix.plants.servo_plant import ServoArm, ServoRun, ServoSpec, play
from tattotronix.robot.description import RobotDescription

#: the servo plant's imperfections (``servo.<name>``)
IMPERFECTIONS = ("quantise", "deadband", "backlash", "nonlinearity", "lag")
#: every imperfection off: an ideal position servo following the program's angles
IDEAL = [f"servo.{k}=false" for k in IMPERFECTIONS]
FRAME_HZ = 50.0
#: a pose in the middle of every joint's range (rad)
Q0 = np.array([0.0, 0.3, -0.6, 0.0, 0.3])

#: a short stretch of the emblem that marks (s)
WINDOW = [100.0, 20.0]


def _score(cfg: Config, tip: np.ndarray, tip_ref: np.ndarray) -> tuple[object, ...]:
    return score_ink(tip, tip_ref, cfg.toolpath.panel_origin, float(cfg.draw.ink_res_mm),
                     float(cfg.toolpath.needle_width_mm))


def _only(name: str | None) -> list[str]:
    """Overrides switching every imperfection off but ``name``."""
    return [f"servo.{k}={str(k == name).lower()}" for k in IMPERFECTIONS]


# --- the plant on tiny synthetic programs --------------------------------------------------

@pytest.fixture(scope="module")
def cfg() -> Config:
    """The default settings."""
    return compose_settings()


@pytest.fixture(scope="module")
def catalogue(cfg: Config, desc: RobotDescription) -> tuple[ServoSpec, ...]:
    """The mounted servos' catalogue figures, every imperfection and the latency off."""
    off = compose_settings(IDEAL).servo
    return joint_servos(cfg.robot, desc.joint_names, default_calibration(), off)


@pytest.fixture(scope="module")
def weightless(cfg: Config, desc: RobotDescription) -> PlantSettings:
    """The plant settings with gravity off (the arm rests wherever it is put)."""
    return replace(PlantSettings.from_settings(cfg.plant, desc.gravity, desc.tip_frame),
                   gravity=0.0)


def _play(mjcf: Path, settings: PlantSettings, specs: tuple[ServoSpec, ...],
          command: np.ndarray) -> ServoRun:
    """``command`` (F, n) played from rest at ``command[0]`` on the servo loop."""
    arm = ServoArm(mjcf, settings, specs, lag=True, ideal_wn=300.0, q0=command[0])
    run = arm.run(command, FRAME_HZ, command[0])
    assert run.healthy
    return run


def test_dead_band_holds_and_stops_half_a_band_short(
        models: tuple[Path, Path], weightless: PlantSettings,
        catalogue: tuple[ServoSpec, ...]) -> None:
    """Commands within half the dead band of rest move nothing; beyond it, w/2 short."""
    w = math.radians(1.0)
    specs = tuple(replace(s, deadband_rad=w) for s in catalogue)
    frames = [20, 75, 75]  # wander, jump out, come back part way
    cmd = np.tile(Q0, (sum(frames), 1))
    rng = np.random.default_rng(7)
    cmd[1:20, 0] += rng.uniform(-0.49 * w, 0.49 * w, 19)
    up = Q0[0] + 3.0 * w
    cmd[20:95, 0] = up
    cmd[40:60, 0] = up - rng.uniform(0.0, 0.98 * w, 20)  # back within the band: held
    down = up - 1.5 * w
    cmd[95:, 0] = down
    run = _play(models[1], weightless, specs, cmd)
    k = np.rint(np.array([20, 95]) / FRAME_HZ / weightless.dt_s).astype(int)
    # the wander: the target and (no gravity) every shaft stay exactly where they were
    np.testing.assert_array_equal(run.target[:k[0], 0], Q0[0])
    np.testing.assert_array_equal(run.shaft[:k[0]], np.tile(Q0, (k[0], 1)))
    # beyond the band: the servo drives to w/2 short of the command, and holds it while the
    # command comes back by less than the band
    np.testing.assert_allclose(run.target[k[0]:k[1], 0], up - 0.5 * w, rtol=0, atol=1e-12)
    assert run.shaft[k[1] - 1, 0] == pytest.approx(up - 0.5 * w, abs=0.01 * w)
    # reversing by more than the band: w/2 short from the other side
    np.testing.assert_allclose(run.target[k[1]:, 0], down + 0.5 * w, rtol=0, atol=1e-12)
    assert run.shaft[-1, 0] == pytest.approx(down + 0.5 * w, abs=0.01 * w)


def test_a_large_step_runs_at_the_no_load_speed(
        models: tuple[Path, Path], weightless: PlantSettings,
        catalogue: tuple[ServoSpec, ...]) -> None:
    """A 60 degree step: the shaft peaks at the no-load speed and takes about step/speed."""
    j = 3  # the wrist's MG996R
    spec = catalogue[j]
    assert spec.type == "MG996R" and spec.latency_s == 0.0
    step = math.radians(60.0)
    cmd = np.tile(Q0, (30, 1))
    cmd[1:, j] += step
    run = _play(models[1], weightless, catalogue, cmd)
    x = run.shaft[:, j] - Q0[j]
    peak = float(np.max(np.abs(run.qd[:, j])))
    assert peak <= 1.02 * spec.speed_rad_s
    assert peak >= 0.95 * spec.speed_rad_s  # it does get there: the drive saturates
    assert np.max(np.abs(run.tau[:, j])) == pytest.approx(spec.stall_nm)
    t90 = float(run.t[np.argmax(x >= 0.9 * step)]) - 1.0 / FRAME_HZ
    assert t90 == pytest.approx(0.9 * step / spec.speed_rad_s, rel=0.25)
    assert x[-1] == pytest.approx(step, abs=1e-4)  # and it lands (no dead band)


@given(steps=st.lists(st.sampled_from([-2e-3, -1e-3, 0.0, 0.0, 1e-3, 2.5e-3]), min_size=1,
                      max_size=400),
       reps=st.integers(1, 40), width=st.sampled_from([1e-3, 2e-3, 0.0173]),
       start=st.one_of(st.none(), st.floats(-0.05, 0.05)))
@settings(max_examples=40, deadline=None)
def test_the_play_operator_in_blocks_is_the_one_step_at_a_time(
        steps: list[float], reps: int, width: float, start: float | None) -> None:
    """Over many blocks (a whole drawing's steps), with ties and still stretches: the same
    numbers, bit for bit, as one step at a time."""
    from tattotronix.plants.servo_plant import _play_blocks, _play_steps

    x = np.cumsum(np.tile(steps, reps * 40))  # up to 640,000 samples
    h = 0.5 * width
    y0 = float(x[0]) if start is None else start
    one_by_one = _play_steps(x - h, x + h, y0).tobytes()
    assert _play_blocks(x - h, x + h, y0).tobytes() == one_by_one
    assert play(x, width, start).tobytes() == one_by_one


def test_backlash_is_the_play_operator() -> None:
    """``play`` on a triangle wave: b/2 behind either way, turning b after the input."""
    a, b = 1.0, 0.3
    knots = [0.0, a, -a, a, -a]
    x = np.interp(np.linspace(0.0, 4.0, 4001), np.arange(5), knots)
    y = play(x, b)
    np.testing.assert_array_equal(play(x, 0.0), x)
    assert y[0] == x[0]  # starts centred in the play
    rising = (np.gradient(x) > 0) & (np.arange(len(x)) > 1000)
    falling = np.gradient(x) < 0
    follows_up = rising & (np.abs(y - (x - 0.5 * b)) < 1e-12)
    follows_down = falling & (np.abs(y - (x + 0.5 * b)) < 1e-12)
    assert follows_up.sum() > 0.8 * rising.sum()
    assert follows_down.sum() > 0.8 * falling.sum()
    assert np.all(y >= x - 0.5 * b - 1e-12) and np.all(y <= x + 0.5 * b + 1e-12)
    assert y.max() == pytest.approx(a - 0.5 * b, abs=1e-12)
    assert y.min() == pytest.approx(-(a - 0.5 * b), abs=1e-12)
    # after each peak the output stays put until the input has come back by b
    for peak in (1000, 2000, 3000):
        after = np.arange(peak, peak + 1000)
        turn = after[np.argmax(y[after] != y[peak])]
        assert abs(x[turn] - x[peak]) == pytest.approx(b, abs=2 * (2 * a / 1000))


def test_the_drive_acts_one_latency_after_the_command(
        models: tuple[Path, Path], weightless: PlantSettings,
        catalogue: tuple[ServoSpec, ...]) -> None:
    """A step reaches the drive ``latency_s`` later (MuJoCo's actuator delay)."""
    latency = 0.0115  # the catalogue's, not a whole number of plant steps
    dt = weightless.dt_s
    sent = 3 / FRAME_HZ
    cmd = np.tile(Q0, (10, 1))
    cmd[3:, 0] += 0.2
    first = {}
    for lag in (0.0, latency):
        specs = tuple(replace(s, latency_s=lag) for s in catalogue)
        run = _play(models[1], weightless, specs, cmd)
        moved = np.flatnonzero(run.shaft[:, 0] != Q0[0])
        first[lag] = float(run.t[moved[0]])
        acts = float(run.t[np.flatnonzero(run.target[:, 0] != Q0[0])[0]])
        assert acts == pytest.approx(sent + lag, abs=dt)
        # nothing moves before the drive acts; the step after, the shaft has
        assert sent + lag < first[lag] <= sent + lag + 2 * dt
        np.testing.assert_array_equal(run.shaft[:moved[0]], np.tile(Q0, (moved[0], 1)))
    assert first[latency] - first[0.0] == pytest.approx(latency, abs=dt)


def test_the_sag_correction_holds_a_loaded_joint_on_its_goal(
        models: tuple[Path, Path], cfg: Config, desc: RobotDescription,
        catalogue: tuple[ServoSpec, ...]) -> None:
    """Under gravity a proportional servo rests ``G(q) / kp`` short of its command (the
    torque it must hold over its gain); sent ``q + G(q) / kp`` (``compensate``'s sag), it
    rests on ``q``."""
    from tattotronix.config.schema import CompensateConfig
    from tattotronix.control.dynamics import Dynamics
    from tattotronix.hardware.servo_model import compensate

    specs = tuple(replace(s, lag=True) for s in catalogue)  # the drive as built, no latency
    settings = PlantSettings.from_settings(cfg.plant, desc.gravity, desc.tip_frame)
    hold = Dynamics(models[0], desc.gravity).gravity(Q0)
    kp = np.array([s.kp for s in specs])
    assert np.abs(hold[1:3]).min() > 0.05  # the shoulder and the elbow carry the arm
    cmd = np.tile(Q0, (100, 1))  # two seconds: the servos settle
    short = Q0 - _play(models[1], settings, specs, cmd).shaft[-1]
    np.testing.assert_allclose(short, hold / kp, rtol=0.03, atol=1e-6)
    sag_only = CompensateConfig(sag=True, lead=False)
    sent = compensate(cmd, specs, sag_only, np.tile(hold, (len(cmd), 1)))
    np.testing.assert_allclose(sent - cmd, np.tile(hold / kp, (len(cmd), 1)), rtol=1e-12)
    rest = _play(models[1], settings, specs, sent).shaft[-1]
    assert np.abs(rest - Q0).max() < 0.03 * np.abs(short).max()
    # a servo without lag (the stiff, exact loop) gets no sag
    np.testing.assert_array_equal(compensate(cmd, catalogue, sag_only,
                                             np.tile(hold, (len(cmd), 1))), cmd)


def test_the_lead_sends_each_command_its_servos_delay_ahead(
        catalogue: tuple[ServoSpec, ...]) -> None:
    """The lead is the latency, half a frame and the drive's own lag (back-EMF over gain);
    the program samples the trajectory that much later: on a ramp, the ramp ahead."""
    from tattotronix.hardware.program import compile_program
    from tattotronix.hardware.servo_model import servo_lead_s

    specs = tuple(replace(s, lag=True, latency_s=0.012) for s in catalogue)
    lead = servo_lead_s(specs, FRAME_HZ)
    want = [0.012 + 0.5 / FRAME_HZ + s.band_rad / s.speed_rad_s for s in specs]
    np.testing.assert_allclose(lead, want, rtol=1e-12)
    assert (servo_lead_s(catalogue, FRAME_HZ) == 0.0).all()  # stiff: nothing to lead
    rate = np.array([0.1, -0.05, 0.08, 0.2, -0.1])  # rad/s, well within every limit
    t = np.array([0.0, 4.0])
    q = np.stack([Q0, Q0 + 4.0 * rate])
    qd = np.tile(rate, (2, 1))
    calib = default_calibration()
    lo, hi, vel = np.full(5, -3.0), np.full(5, 3.0), np.full(5, 5.0)
    plain = compile_program(t, q, qd, calib, lo, hi, vel)
    ahead = compile_program(t, q, qd, calib, lo, hi, vel, lead_s=lead)
    np.testing.assert_allclose(ahead.q, plain.q)  # the plan's frames are the plan's
    inside = plain.t + lead.max() <= 4.0
    np.testing.assert_allclose(ahead.q_sent[inside] - plain.q_sent[inside],
                               np.tile(rate * lead, (int(inside.sum()), 1)), atol=1e-12)
    np.testing.assert_allclose(ahead.q_sent[-1], q[-1], atol=1e-12)  # held at the end


# --- the measured pulse map ----------------------------------------------------------------

def _measured(w: np.ndarray) -> np.ndarray:
    """A bent servo's angle (deg) at widths (us): the declared line plus 1.5 deg of bend."""
    return (w - 1500.0) / 11.1111 + 1.5 * np.sin(np.pi * (w - 1500.0) / 1000.0)


def _with_points(points: Any, order: int | None = None) -> Any:
    """The declared calibration with ``points`` (and ``fit_order``) on joint_1."""
    m: Any = copy.deepcopy(default_calibration_mapping())
    m["joints"]["joint_1"]["points"] = points
    if order is not None:
        m["joints"]["joint_1"]["fit_order"] = order
    return m


def test_measured_points_round_trip_and_the_fit_inverts() -> None:
    """``points`` survive from_mapping/to_mapping, and the fit's inverse undoes it."""
    widths = np.linspace(500.0, 2500.0, 9)
    pts = [[float(w), float(a)] for w, a in zip(widths, _measured(widths), strict=True)]
    calib = Calibration.from_mapping(_with_points(pts[::-1], 3))  # any order: sorted
    fit = calib.joint("joint_1").a.fit
    assert fit is not None and fit.order == 3 and fit.span_us == (500.0, 2500.0)
    assert calib.joint("joint_2").a.fit is None
    back: Any = calib.to_mapping()
    assert back["joints"]["joint_1"]["points"] == pts
    assert back["joints"]["joint_1"]["fit_order"] == 3
    assert Calibration.from_mapping(back) == calib
    w = np.linspace(510.0, 2490.0, 397)
    np.testing.assert_allclose(fit.pulse_us(fit.angle(w)), w, rtol=0, atol=0.05)
    np.testing.assert_allclose(np.degrees(fit.angle(widths)), _measured(widths), atol=0.2)
    # the joint sends the width the fit gives for an angle
    ch = calib.joint("joint_1").a
    assert ch.pulse_us(math.radians(30.0)) == pytest.approx(
        float(fit.pulse_us(math.radians(30.0))), abs=1e-9)


@pytest.mark.parametrize("points, order, says", [
    ([[1500, 0]], None, r"joint_1\.points: 1 measured pair"),
    ([[1000, -45], [1000, -40], [2000, 45]], None, r"joint_1\.points: a width is measured"),
    ([["15OO", 0], [2000, 45]], None, r"joint_1\.points\[0\] width: '15OO' is not a number"),
    ([[500, -90], [1500, 0], [2500, -90]], 2, r"joint_1\.points: the order-2 fit .* turns"),
])
def test_bad_points_are_refused_naming_the_joint(points: Any, order: int | None,
                                                 says: str) -> None:
    """One pair, a repeated width, a non-number, a fit that turns back: each refused."""
    with pytest.raises(CalibrationError, match=says):
        Calibration.from_mapping(_with_points(points, order))


def test_measured_fit_reproduces_the_bent_servo(cfg: Config) -> None:
    """The simulated calibration recovers the servo's own map to the protractor's reading."""
    s = cfg.servo
    spec = replace(_bent(), nonlinearity_rad=math.radians(2.0))
    ch = default_calibration().joint("joint_1").a
    fit = measure_fit(spec, ch, s.fit_points, s.fit_order, s.protractor_deg)
    assert len(fit.points) == s.fit_points and fit.order == s.fit_order
    w = np.linspace(ch.min_us, ch.max_us, 2001)
    true = np.degrees(spec.true_angle(ch, w))
    err = np.max(np.abs(np.degrees(fit.angle(w)) - true))
    assert err <= 0.5 * s.protractor_deg + fit.residual_deg()
    line = np.max(np.abs(np.degrees((w - ch.zero_us) / ch.us_per_rad) - true))
    assert line == pytest.approx(2.0, abs=1e-3) and err < 0.2 * line
    # the protractor's readings, to its resolution
    deg = np.array([p[1] for p in fit.points]) / s.protractor_deg
    np.testing.assert_allclose(deg, np.round(deg), rtol=0, atol=1e-9)


def _bent() -> ServoSpec:
    """A servo with no imperfection (the tests switch one on)."""
    return ServoSpec(type="bent", bus=False, deadband_rad=0.0, stall_nm=1.0, speed_rad_s=7.0,
                     band_rad=0.05, backlash_rad=0.0, nonlinearity_rad=0.0,
                     armature_kgm2=0.002, latency_s=0.0, step_rad=0.0)


# --- bad input -----------------------------------------------------------------------------

def test_an_unknown_servo_type_lists_the_catalogue(desc: RobotDescription) -> None:
    """``servo.type=NOPE`` is refused with the catalogue's names."""
    cfg = compose_settings(["backend=servo", "servo.type=NOPE"])
    with pytest.raises(TattotronixError, match=r"servo\.type=NOPE.*MG996R, SG90, STS3215"):
        joint_servos(cfg.robot, desc.joint_names, default_calibration(), cfg.servo)


@pytest.mark.parametrize("window", [[0.5, 1e-12], [1.005, 1.0]])
def test_a_window_shorter_than_two_frames_is_refused(draw_data: Path, desc: RobotDescription,
                                                     window: list[float]) -> None:
    """A stretch inside one servo frame (mid-drawing, or the last part frame) is refused."""
    cfg = compose_settings(["backend=servo"])
    t = np.array([0.0, 1.01])  # 51 whole frames and a part one
    q = np.tile(Q0, (2, 1))
    drawing = Drawing("still", t, q, np.zeros_like(q), np.ones(2, dtype=np.int8), "planned")
    with pytest.raises(TattotronixError, match="shorter than two servo frames"):
        run_servo_loop(cfg, draw_data, desc, drawing, window=window)


# --- the emblem: the ideal servo and the corrections ---------------------------------------

@pytest.fixture(scope="module")
def emblem(desc: RobotDescription, models_data: Path) -> Drawing:
    """The built-in emblem drawing, planned."""
    return resolve_drawing(compose_settings(), models_data, desc)


@pytest.fixture(scope="module")
def chain(desc: RobotDescription) -> Chain:
    """The kinematic chain (FK of the tip)."""
    return Chain.from_description(desc)


def _tips(chain: Chain, loop: ClosedLoop) -> tuple[np.ndarray, np.ndarray]:
    """The simulated and the planned tip at every tick, m."""
    return chain.fk(loop.run.q)[0], chain.fk(loop.run.ref.q[:len(loop.run.q)])[0]


def test_the_ideal_servo_draws_the_mujoco_plants_ink(desc: RobotDescription, emblem: Drawing,
                                                     models_data: Path, chain: Chain) -> None:
    """Every imperfection off, the servo plant's ink is the MuJoCo plant's, to the needle."""
    cfg_mj = compose_settings(["backend=mujoco"])
    cfg_sv = compose_settings(["backend=servo", *IDEAL])
    mj = run_closed_loop(cfg_mj, models_data, desc, emblem, window=WINDOW)
    sv = run_servo_loop(cfg_sv, models_data, desc, emblem, window=WINDOW)
    assert mj.run.verdict == "ok" and sv.run.verdict == "ok"
    np.testing.assert_array_equal(sv.run.t, mj.run.t)  # the same plant steps
    tip_mj, tip_ref = _tips(chain, mj)
    tip_sv, _ = _tips(chain, sv)
    needle = float(cfg_sv.toolpath.needle_width_mm)
    grid, ink_sv, ink_mj, ink = _score(cfg_sv, tip_sv, tip_mj)
    assert ink == compare_ink(ink_sv, ink_mj, grid.res_mm)
    assert ink.sim_px > 1000 and ink.plan_px > 1000  # the window marks
    assert ink.max_dev_mm <= needle
    # and each against the plan
    assert _score(cfg_sv, tip_sv, tip_ref)[3].max_dev_mm <= needle
    assert _score(cfg_mj, tip_mj, tip_ref)[3].max_dev_mm <= needle


@pytest.mark.parametrize("imperfection, correction", [
    ("backlash", "backlash"), ("deadband", "deadband"), ("nonlinearity", "fit"),
    ("lag", "sag"), ("lag", "lead")])
def test_each_correction_halves_its_own_error(desc: RobotDescription, emblem: Drawing,
                                              models_data: Path, chain: Chain,
                                              imperfection: str, correction: str) -> None:
    """One imperfection alone: its correction at least halves the mean marking error."""
    mean = {}
    for on in (False, True):
        cfg = compose_settings(["backend=servo", *_only(imperfection),
                                f"hardware.compensate.{correction}={str(on).lower()}"])
        loop = run_servo_loop(cfg, models_data, desc, emblem, window=WINDOW)
        assert loop.run.verdict == "ok"
        summary: Any = loop.controller
        assert summary["compensate"][correction] is on
        err = loop.errors(chain, float(cfg.draw.settle_periods))
        assert err.down.sum() > 100  # the window marks
        mean[on] = float(np.mean(err.error_m[err.down])) * 1e6  # marking_mean_um
    assert mean[False] > 100.0  # the imperfection alone costs a tenth of a millimetre
    assert mean[True] <= 0.5 * mean[False]


def test_the_simulated_calibration_fits_as_a_calibration_file_does() -> None:
    """``servo.fit_order`` (the servo plant's calibration) is a calibration file's default
    order (``hardware.servos.DEFAULT_FIT_ORDER``: ``config`` sits below ``hardware`` and
    cannot import it)."""
    from tattotronix.config.schema import ServoPlantConfig
    from tattotronix.hardware.servos import DEFAULT_FIT_ORDER

    assert ServoPlantConfig().fit_order == DEFAULT_FIT_ORDER
