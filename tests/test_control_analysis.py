"""Loop facts (docs/original.md, "5.3 Tuning by pole placement" and "5.4 Loop facts"): gains,
modes, the sampled loop, overshoots."""

from __future__ import annotations

import json
import math
from pathlib import Path

import control
import numpy as np
import pytest

from tattotronix.control import analysis
from tattotronix.control.analysis import (
    coupled_zeta_min,
    loop_report,
    modal_gains,
    mode_damping,
    mode_loop_matrix,
    pole_placement_gains,
    sampled_boundary_numeric,
    sampled_boundary_wnT,
    spectral_radius,
    step_overshoot_pct,
)
from tattotronix.control.dynamics import Dynamics

GRAVITY = 9.80665
Q_REF_TUNE = np.array([-0.0112645418, 0.5611492471, 0.4417099134, -7.58e-9, 0.5679371434])
WN = 20.0

# the original's table (docs/original.md, "5.3 Tuning by pole placement")
J_EFF = np.array([3.601969e-3, 2.663281e-3, 6.271488e-4, 1.820259e-5, 3.017853e-5])
KP = np.array([4.3224, 3.1959, 0.7526, 0.0218, 0.0362])
KI = np.array([28.8158, 21.3063, 5.0172, 0.1456, 0.2414])
KD = np.array([0.21612, 0.15980, 0.03763, 0.00109, 0.00181])

OVERSHOOT_PID_PI_D = 500.0 / math.e**3  # 24.89 %
OVERSHOOT_PID = 100.0 * (math.sqrt(3.0) - 1.0) * math.exp(math.sqrt(3.0) - 3.0)  # 20.60 %


def closed_form_loop(lam: float, x: float, c: float) -> np.ndarray:
    """A + lam B k of the sampled loop (docs/original.md, "5.4 Loop facts")."""
    a = np.array([[1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])
    b = np.array([c, 1.0, 0.0])
    k = np.array([-(3 * x**2 + x**3), -3 * x, x**3])
    return a + lam * np.outer(b, k)


@pytest.fixture(scope="module")
def tune_pose(models: tuple[Path, Path]) -> tuple[np.ndarray, np.ndarray]:
    """M and J_eff of the generated model at q_ref_tune."""
    dyn = Dynamics(models[0], GRAVITY)
    return dyn.mass_matrix(Q_REF_TUNE), dyn.effective_inertia(Q_REF_TUNE)


@pytest.fixture(scope="module")
def lam_tune(tune_pose: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    return modal_gains(*tune_pose)


# ------------------------------------------------------------------------ gains, modes


def test_effective_inertia_and_gains_match_the_reference(tune_pose) -> None:
    _, j = tune_pose
    np.testing.assert_allclose(j, J_EFF, rtol=1e-5)
    kp, ki, kd = pole_placement_gains(j, WN)
    np.testing.assert_allclose(kp, KP, rtol=5e-3)
    np.testing.assert_allclose(ki, KI, rtol=5e-3)
    np.testing.assert_allclose(kd, KD, rtol=5e-3)


def test_gains_scale_with_wn() -> None:
    kp, ki, kd = pole_placement_gains([1.0], 160.0)
    assert (kp[0], kd[0], ki[0]) == pytest.approx((76800.0, 480.0, 4.096e6))


def test_modal_gains_at_the_tuning_pose(lam_tune) -> None:
    assert lam_tune.shape == (5,)
    assert np.all(np.diff(lam_tune) <= 0.0)
    assert round(float(lam_tune[0]), 2) == 2.11
    assert round(float(lam_tune[-1]), 2) == 0.21
    assert float(lam_tune.sum()) == pytest.approx(5.0, rel=1e-10)
    assert round(coupled_zeta_min(lam_tune), 2) == 0.17


def test_modal_gains_are_the_eigenvalues_of_minv_j(tune_pose, lam_tune) -> None:
    m, j = tune_pose
    direct = np.sort(np.linalg.eigvals(np.linalg.solve(m, np.diag(j))).real)[::-1]
    np.testing.assert_allclose(lam_tune, direct, rtol=1e-9)


def test_mode_damping() -> None:
    assert mode_damping(1.0) == pytest.approx(1.0, abs=1e-6)  # triple pole at -wn
    assert mode_damping(1.0 / 9.0 + 1e-9) == pytest.approx(0.0, abs=1e-6)  # Routh-Hurwitz
    assert mode_damping(0.1) < 0.0  # unstable below 1/9
    assert coupled_zeta_min([2.0, 0.5, 1.0]) == mode_damping(0.5)


# ----------------------------------------------------------------------- sampled loop


@pytest.mark.parametrize(("substeps", "c"), [(None, 0.5), (4, 5.0 / 8.0), (1, 1.0)])
@pytest.mark.parametrize("lam", [0.21, 1.0, 2.11])
def test_mode_loop_matrix_is_a_plus_lam_b_k(substeps, c, lam) -> None:
    for x in (0.05, 0.16, 0.4):
        np.testing.assert_allclose(mode_loop_matrix(lam, x, substeps),
                                   closed_form_loop(lam, x, c), atol=1e-12)


@pytest.mark.parametrize(("lam", "x"), [(0.21, 0.05), (1.0, 0.3), (2.11, 0.7)])
def test_exact_hold_plant_is_python_control_zoh(lam, x) -> None:
    ours = analysis._plant(lam, x, None)
    cont = control.ss([[0.0, 1.0], [0.0, 0.0]], [[0.0], [lam]], np.eye(2), np.zeros((2, 1)))
    ref = control.sample_system(cont, x, "zoh")
    np.testing.assert_allclose(ours.A, ref.A, atol=1e-14)
    np.testing.assert_allclose(ours.B, ref.B, atol=1e-14)
    assert ours.dt == ref.dt == x


@pytest.mark.parametrize("substeps", [None, 1, 4])
@pytest.mark.parametrize(("lam", "x"), [(0.21, 0.05), (1.0, 0.3), (2.11, 0.7)])
def test_the_closed_loop_is_python_control_feedback(lam, x, substeps) -> None:
    plant, law = analysis._plant(lam, x, substeps), analysis._controller(x)
    ref = control.feedback(control.ss(plant.A, plant.B, plant.C, plant.D, dt=x),
                           control.ss(law.A, law.B, law.C, law.D, dt=x), sign=1)
    np.testing.assert_allclose(analysis._positive_feedback(plant, law), ref.A, atol=1e-13)


def test_closed_loop_poles_are_python_control_poles() -> None:
    loop = control.ss(mode_loop_matrix(1.7, 0.2), np.zeros((3, 1)), np.eye(3),
                      np.zeros((3, 1)), dt=0.2)
    assert np.max(np.abs(control.poles(loop))) == pytest.approx(spectral_radius(1.7, 0.2))


def test_sampled_boundary_at_the_tuning_pose(lam_tune) -> None:
    lam_max = float(lam_tune[0])
    closed = sampled_boundary_wnT(lam_max)
    assert closed == pytest.approx(0.316, rel=0.01)
    assert sampled_boundary_numeric(lam_max) == pytest.approx(closed, abs=1e-6)
    assert spectral_radius(lam_max, 0.99 * closed) < 1.0 < spectral_radius(lam_max, 1.01 * closed)
    # the softer modes are stable further out: the stiffest one sets the boundary
    assert all(spectral_radius(float(v), 0.99 * closed) < 1.0 for v in lam_tune)


def test_single_axis_boundary() -> None:
    assert sampled_boundary_wnT(1.0) == pytest.approx(2.0 / 3.0)
    assert sampled_boundary_numeric(1.0) == pytest.approx(2.0 / 3.0, abs=1e-6)


def test_euler_substeps_boundary(lam_tune) -> None:
    """Euler sub-steps move the boundary in, by O(1/N).

    With c = (N+1)/(2N) the characteristic polynomial at z = -1 is
    -8 + 12 lam x + lam (6 x^2 + x^3)/N, so for N = 1 the boundary is
    (x + 2)^3 = 8 (1 + 1/lam): x = 2 ((1 + 1/lam)^(1/3) - 1).
    """
    lam_max = float(lam_tune[0])
    exact = sampled_boundary_wnT(lam_max)
    b1 = sampled_boundary_numeric(lam_max, 1)
    assert math.isfinite(b1) and 0.0 < b1 < exact
    assert b1 == pytest.approx(2.0 * ((1.0 + 1.0 / lam_max) ** (1.0 / 3.0) - 1.0), abs=1e-9)
    assert b1 == pytest.approx(0.2762, abs=1e-4)
    b4 = sampled_boundary_numeric(lam_max, 4)
    assert b4 == pytest.approx(0.3039, abs=1e-4)
    bounds = [sampled_boundary_numeric(lam_max, n) for n in (1, 4, 16, 100, 1000)]
    assert all(a < b < exact for a, b in zip(bounds, bounds[1:], strict=False))
    assert exact - bounds[-1] < 1e-4
    assert sampled_boundary_numeric(1.0, 1) == pytest.approx(16.0 ** (1.0 / 3.0) - 2.0,
                                                              abs=1e-9)


# ----------------------------------------------------------------------- step response


def test_step_overshoot() -> None:
    pi_d = step_overshoot_pct(derivative_on_error=False)
    pid = step_overshoot_pct(derivative_on_error=True)
    for num, ours in (([3.0, 1.0], pi_d), ([3.0, 3.0, 1.0], pid)):  # python-control's
        info = control.step_info(control.tf(num, [1.0, 3.0, 3.0, 1.0]),
                                 timepts=np.linspace(0.0, 20.0, 20001))
        assert ours == pytest.approx(float(info["Overshoot"]), abs=1e-5)
    assert pi_d == pytest.approx(24.9, abs=0.05)
    assert pid == pytest.approx(20.6, abs=0.05)
    assert pi_d == pytest.approx(OVERSHOOT_PID_PI_D, abs=0.01)
    assert pid == pytest.approx(OVERSHOOT_PID, abs=0.01)


# ----------------------------------------------------------------------------- report


def test_loop_report(tune_pose) -> None:
    m, j = tune_pose
    rep = loop_report(m, j, WN, 1000.0)
    assert json.loads(json.dumps(rep)) == rep
    for key, value in rep.items():
        values = value if isinstance(value, list) else [value]
        assert all(type(v) is float for v in values), key
    assert rep["modal_gain"][0] == pytest.approx(2.11, abs=0.005)
    assert rep["sampled_boundary_wnT"] == pytest.approx(0.316, rel=0.01)
    assert rep["sampled_boundary_numeric_wnT"] == pytest.approx(rep["sampled_boundary_wnT"],
                                                                abs=1e-6)
    assert rep["wnT"] == pytest.approx(0.02)
    assert rep["margin"] == pytest.approx(rep["sampled_boundary_numeric_wnT"] / 0.02)
    np.testing.assert_allclose(rep["kp"], KP, rtol=5e-3)
    np.testing.assert_allclose(rep["j_eff"], J_EFF, rtol=1e-5)
    assert rep["step_overshoot_single_axis_pct"] == pytest.approx(24.9, abs=0.05)
    assert rep["step_overshoot_ff_pct"] == pytest.approx(20.6, abs=0.05)
    rep4 = loop_report(m, j, 160.0, 1000.0, substeps=4)
    assert rep4["sampled_boundary_numeric_wnT"] < rep4["sampled_boundary_wnT"]
    assert rep4["wnT"] == pytest.approx(0.16)


# -------------------------------------------------------------------------- bad inputs


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
def test_bad_scalars_are_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="wn"):
        pole_placement_gains([1.0], bad)
    with pytest.raises(ValueError, match="lam"):
        mode_damping(bad)
    with pytest.raises(ValueError, match="lam_max"):
        sampled_boundary_wnT(bad)
    with pytest.raises(ValueError, match="x="):
        mode_loop_matrix(1.0, bad)
    with pytest.raises(ValueError, match="lam"):
        spectral_radius(bad, 0.1)
    with pytest.raises(ValueError, match="rate_hz"):
        loop_report(np.eye(2), [1.0, 1.0], 20.0, bad)
    with pytest.raises(ValueError, match="wn"):
        loop_report(np.eye(2), [1.0, 1.0], bad, 1000.0)


def test_bad_arrays_and_options_are_refused() -> None:
    with pytest.raises(ValueError, match="j_eff"):
        pole_placement_gains([1.0, -2.0], 20.0)
    with pytest.raises(ValueError, match="j_eff"):
        pole_placement_gains([1.0, math.nan], 20.0)
    with pytest.raises(ValueError, match="lams"):
        coupled_zeta_min([])
    with pytest.raises(ValueError, match="shape"):
        modal_gains(np.eye(3), [1.0, 1.0])
    with pytest.raises(ValueError, match="positive-definite"):
        modal_gains(np.diag([1.0, -1.0]), [1.0, 1.0])
    with pytest.raises(ValueError, match="symmetric"):
        modal_gains([[1.0, 0.5], [0.0, 1.0]], [1.0, 1.0])
    with pytest.raises(ValueError, match="non-finite"):
        modal_gains([[1.0, math.nan], [math.nan, 1.0]], [1.0, 1.0])
    with pytest.raises(ValueError, match="substeps"):
        mode_loop_matrix(1.0, 0.1, 0)
    with pytest.raises(ValueError, match="substeps"):
        sampled_boundary_numeric(1.0, True)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="lam=0.1"):
        sampled_boundary_numeric(0.1)  # continuous-time unstable: no boundary


def test_python_control_is_left_to_the_figures_and_the_tests() -> None:
    """Importing every module of the library (what a stage's start-up imports) and
    analysing a loop (what every simulated drawing and study case does) leave
    python-control and scipy.signal out: they cost seconds of every stage's start-up.
    The loop analysis computes what python-control would, in numpy (the tests above hold
    the two equal)."""
    import subprocess
    import sys

    code = ("import importlib, pkgutil, sys, numpy, tattotronix\n"
            "for m in pkgutil.walk_packages(tattotronix.__path__, 'tattotronix.'):\n"
            "    importlib.import_module(m.name)\n"
            "from tattotronix.control.analysis import loop_report\n"
            "loop_report(numpy.diag([2.0, 1.0]), [1.0, 1.0], 160.0, 1000.0, 4)\n"
            "print('control' in sys.modules, 'scipy.signal' in sys.modules)\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, cwd=Path(__file__).resolve().parents[1])
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["False", "False"], run.stdout
