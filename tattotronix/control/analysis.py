"""Closed-form and sampled-loop facts of the joint controller (docs/control.md, "Loop facts";
the original's: docs/original.md, "5.3 Tuning by pole placement" and "5.4 Loop facts").

Each joint is a double integrator ``J qdd = tau`` tuned by pole placement with all three
poles at ``-wn``::

    Kp = 3 J wn^2 (N m/rad),   Kd = 3 J wn (N m s/rad),   Ki = J wn^3 (N m/(rad s))

with ``J = J_eff,i = 1 / (M^-1)_ii`` (kg m^2). Because every gain is a multiple of
``diag(J_eff)``, the linearised arm splits into modes, one per eigenvalue ``lam`` of
``M^-1 diag(J_eff)`` (real, positive, trace = n); each mode is the single axis with its
plant gain multiplied by ``lam``: characteristic polynomial ``s^3 + lam (3 wn s^2 +
3 wn^2 s + wn^3)``. A mode with ``lam < 1/9`` is unstable.

Sampled loop (controller period ``T`` s, torque held over the period). With the
controller's order of operations (the integral takes the new error *before* the torque)::

    I_k = I_{k-1} + e_k T,   tau_k = Kp e_k + Ki I_k - Kd qd_k

the per-mode map on the state ``(q, T qd, I_{k-1}/T)`` (rad, rad, rad) is
``A + lam B k`` with ``x = wn T``, ``A = [[1,1,0],[0,1,0],[-1,0,1]]``, ``B = [c, 1, 0]^T``
and ``k = [-(3x^2 + x^3), -3x, x^3]``; ``c = 1/2`` for an exact hold and
``c = (N+1)/(2N)`` for ``N`` semi-implicit Euler plant sub-steps per period. The map is
stable for ``wn T < 2/(3 lam_max)`` (exact hold). Everything here is scale-free: the
sampled-loop functions work in units ``J = 1``, ``wn = 1`` so that ``T = x``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypedDict

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

__all__ = [
    "LoopReport",
    "coupled_zeta_min",
    "loop_report",
    "modal_gains",
    "mode_damping",
    "mode_loop_matrix",
    "pole_placement_gains",
    "sampled_boundary_numeric",
    "sampled_boundary_wnT",
    "spectral_radius",
    "step_overshoot_pct",
]

Array = NDArray[np.float64]

#: Smallest modal gain with a stable continuous loop (Routh-Hurwitz: 9 lam^2 > lam).
LAMBDA_MIN_STABLE = 1.0 / 9.0


# ----------------------------------------------------------------------------- checks


def _positive(name: str, value: float) -> float:
    """``value`` as a float, or ValueError naming it when it is not positive and finite."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={value!r} is not a number") from None
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name}={value!r} must be positive and finite")
    return v


def _positive_array(name: str, value: ArrayLike) -> Array:
    """``value`` as a non-empty float64 vector, every entry positive and finite."""
    a = np.asarray(value, dtype=np.float64)
    if a.ndim != 1 or a.size == 0:
        raise ValueError(f"{name}={a.tolist()} must be a non-empty vector")
    if not (np.all(np.isfinite(a)) and np.all(a > 0.0)):
        raise ValueError(f"{name}={a.tolist()} must be positive and finite")
    return a


def _substeps(substeps: int | None) -> int | None:
    """``None`` (exact hold) or a plant sub-step count >= 1."""
    if substeps is None:
        return None
    if isinstance(substeps, bool) or not isinstance(substeps, int | np.integer) or substeps < 1:
        raise ValueError(f"substeps={substeps!r} must be None (exact hold) or an int >= 1")
    return int(substeps)


# ------------------------------------------------------------------ gains and modes


def pole_placement_gains(j_eff: ArrayLike, wn: float) -> tuple[Array, Array, Array]:
    """Gains placing all three poles of each axis at ``-wn``.

    Args:
        j_eff: effective inertias ``J_eff,i`` (kg m^2), one per joint.
        wn: the bandwidth (rad/s).

    Returns:
        ``(Kp, Ki, Kd)`` in N m/rad, N m/(rad s) and N m s/rad:
        ``3 J wn^2``, ``J wn^3`` and ``3 J wn``.

    Raises:
        ValueError: ``wn`` or an inertia is not positive and finite.
    """
    j = _positive_array("j_eff", j_eff)
    w = _positive("wn", wn)
    return 3.0 * j * w**2, j * w**3, 3.0 * j * w


def modal_gains(mass_matrix: ArrayLike, j_eff: ArrayLike) -> Array:
    """Eigenvalues ``lam`` of ``M^-1 diag(J_eff)``, sorted descending (dimensionless).

    ``M^-1 diag(J)`` is similar to the symmetric positive-definite
    ``diag(J)^1/2 M^-1 diag(J)^1/2``, so the eigenvalues are real and positive; with
    ``J = J_eff`` their sum is n.

    Args:
        mass_matrix: (n, n) joint-space mass matrix (kg m^2), symmetric positive-definite.
        j_eff: (n,) the inertias the gains were placed on (kg m^2).

    Raises:
        ValueError: shapes disagree, values are not finite, ``M`` is not symmetric
            positive-definite or an inertia is not positive.
    """
    m = np.asarray(mass_matrix, dtype=np.float64)
    j = _positive_array("j_eff", j_eff)
    if m.shape != (j.size, j.size):
        raise ValueError(f"mass_matrix of shape {m.shape} does not match j_eff of "
                         f"length {j.size}")
    if not np.all(np.isfinite(m)):
        raise ValueError(f"mass_matrix={m.tolist()} has non-finite entries")
    if not np.allclose(m, m.T, rtol=1e-9, atol=1e-12 * float(np.max(np.abs(m)))):
        raise ValueError(f"mass_matrix={m.tolist()} is not symmetric")
    try:
        np.linalg.cholesky(m)
    except np.linalg.LinAlgError:
        raise ValueError(f"mass_matrix={m.tolist()} is not positive-definite") from None
    s = np.sqrt(j)
    sym = s[:, None] * np.linalg.inv(m) * s[None, :]
    lam = np.linalg.eigvalsh(0.5 * (sym + sym.T))
    return np.asarray(lam[::-1], dtype=np.float64)


def mode_damping(lam: float) -> float:
    """Smallest damping ratio among the roots of ``s^3 + lam (3 s^2 + 3 s + 1)``.

    The polynomial is the mode's characteristic polynomial with ``s`` in units of ``wn``
    (the result is scale-free). For each root ``zeta = -Re(s) / |s|``; negative means
    unstable (``lam < 1/9``).

    Args:
        lam: the modal gain (dimensionless, > 0).

    Raises:
        ValueError: ``lam`` is not positive and finite.
    """
    lv = _positive("lam", lam)
    roots = np.roots([1.0, 3.0 * lv, 3.0 * lv, lv])
    return float(np.min(-roots.real / np.abs(roots)))


def coupled_zeta_min(lams: ArrayLike) -> float:
    """The smallest damping ratio over all modes (dimensionless), see :func:`mode_damping`.

    Args:
        lams: the modal gains (dimensionless), e.g. from :func:`modal_gains`.

    Raises:
        ValueError: empty, or a gain is not positive and finite.
    """
    lam = _positive_array("lams", lams)
    return min(mode_damping(float(v)) for v in lam)


# ------------------------------------------------------------------------ sampled loop


def sampled_boundary_wnT(lam_max: float) -> float:
    """Closed-form stability boundary of the sampled loop with an exact hold.

    The characteristic polynomial at ``z = -1`` is ``4 (3 lam x - 2)``, so the stiffest
    mode leaves the unit circle at ``x = wn T = 2 / (3 lam_max)`` (rad/s times s).

    Args:
        lam_max: the largest modal gain (dimensionless).

    Raises:
        ValueError: ``lam_max`` is not positive and finite.
    """
    return 2.0 / (3.0 * _positive("lam_max", lam_max))


@dataclass(frozen=True)
class SampledSystem:
    """A discrete-time state-space system ``x+ = A x + B u``, ``y = C x + D u`` of period
    ``dt`` (python-control's ``StateSpace`` fields, without its per-call overhead, which
    dominated the boundary search; tests/test_control_analysis.py holds the two equal)."""

    A: Array
    B: Array
    C: Array
    D: Array
    dt: float


def _plant(lam: float, x: float, substeps: int | None) -> SampledSystem:
    """One control period of the mode's plant ``qdd = lam tau`` (J = 1, wn = 1, T = x).

    State ``(q, qd)``, input ``tau`` held over the period, output the full state. Both
    discretisations act on the augmented state ``(q, qd, tau)`` with ``tau`` constant:
    the exact hold is the matrix exponential of its generator over ``x`` (what
    ``control.sample_system(..., "zoh")`` computes; the generator is nilpotent,
    ``G^3 = 0``, so the exponential series ends at ``G^2``), Euler the ``N``-th power of
    one sub-step.
    """
    if substeps is None:
        gen = x * np.array([[0.0, 1.0, 0.0], [0.0, 0.0, lam], [0.0, 0.0, 0.0]])
        period = np.eye(3) + gen + 0.5 * (gen @ gen)  # = expm(gen), exactly
    else:
        # semi-implicit Euler, N sub-steps of h: v += lam tau h; q += v h
        h = x / substeps
        step = np.array([[1.0, h, lam * h * h], [0.0, 1.0, lam * h], [0.0, 0.0, 1.0]])
        period = np.linalg.matrix_power(step, substeps)
    return SampledSystem(period[:2, :2], period[:2, 2:], np.eye(2), np.zeros((2, 1)), x)


def _controller(x: float) -> SampledSystem:
    """The PI-D law in normalised units (J = 1, wn = 1, T = x), regulating to ``q_r = 0``.

    State ``I_{k-1}`` (rad s), input the measurement ``(q, qd)``, output ``tau``:
    ``I_k = I_{k-1} - q T`` and ``tau = -Kp q + Ki I_k - Kd qd``.
    """
    kp, ki, kd = (float(g[0]) for g in pole_placement_gains([1.0], 1.0))
    return SampledSystem(np.array([[1.0]]), np.array([[-x, 0.0]]), np.array([[ki]]),
                         np.array([[-kp - ki * x, -kd]]), x)


def _positive_feedback(plant: SampledSystem, law: SampledSystem) -> Array:
    """The state matrix of ``plant`` with ``law`` in positive feedback (``u = law(y)``,
    no reference; python-control's ``feedback(plant, law, sign=1)``), state ``(plant's,
    law's)``. The plant has no feedthrough, so the loop is never algebraic."""
    top = np.hstack([plant.A + plant.B @ law.D @ plant.C, plant.B @ law.C])
    bottom = np.hstack([law.B @ plant.C, law.A])
    return np.vstack([top, bottom])


def mode_loop_matrix(lam: float, x: float, substeps: int | None = None) -> Array:
    """The closed-loop map of one mode over one control period, state ``(q, T qd, I/T)``.

    Built from the plant's discretisation (exact zero-order hold, or ``N`` semi-implicit
    Euler sub-steps) closed through the controller law (as ``control.feedback`` closes
    it), then expressed in the state ``(q, T qd, I_{k-1}/T)`` (all in rad). It equals
    ``A + lam B k`` of the module docstring.

    Args:
        lam: the modal gain (dimensionless).
        x: ``wn T``, the bandwidth times the control period (dimensionless).
        substeps: ``None`` for an exact zero-order hold, or the number ``N`` of
            semi-implicit Euler plant sub-steps per control period.

    Returns:
        (3, 3) array.

    Raises:
        ValueError: ``lam`` or ``x`` not positive and finite, or a bad ``substeps``.
    """
    lv = _positive("lam", lam)
    xv = _positive("x", x)
    n = _substeps(substeps)
    loop = _positive_feedback(_plant(lv, xv, n), _controller(xv))
    # physical state (q, qd, I_{k-1}) -> (q, T qd, I_{k-1} / T)
    scale = np.array([1.0, xv, 1.0 / xv])
    return np.asarray(scale[:, None] * loop / scale[None, :], dtype=np.float64)


def spectral_radius(lam: float, x: float, substeps: int | None = None) -> float:
    """Largest pole modulus of the sampled mode (dimensionless; < 1 is stable).

    Args:
        lam: the modal gain (dimensionless).
        x: ``wn T`` (dimensionless).
        substeps: as for :func:`mode_loop_matrix`.
    """
    return float(np.max(np.abs(np.linalg.eigvals(mode_loop_matrix(lam, x, substeps)))))


def sampled_boundary_numeric(lam: float, substeps: int | None = None) -> float:
    """The ``x = wn T`` where the sampled mode first becomes unstable, found numerically.

    Scans ``x`` upwards for the first point with spectral radius >= 1, then refines the
    crossing with Brent's method (to ~1e-13 in ``x``). For an exact hold this equals
    :func:`sampled_boundary_wnT`.

    Args:
        lam: the modal gain (dimensionless, > 1/9: smaller gains are unstable at any rate).
        substeps: as for :func:`mode_loop_matrix`.

    Raises:
        ValueError: ``lam`` not above 1/9 or not finite, a bad ``substeps``, or no crossing.
    """
    lv = _positive("lam", lam)
    n = _substeps(substeps)
    if lv <= LAMBDA_MIN_STABLE:
        raise ValueError(f"lam={lam!r} <= 1/9: the mode is unstable in continuous time, "
                         "there is no stable sampling rate")

    def excess(xv: float) -> float:
        return spectral_radius(lv, xv, n) - 1.0

    grid = np.geomspace(1e-3, max(20.0, 20.0 / lv), 150)  # steps of ~6 %
    lo = float(grid[0])
    if excess(lo) >= 0.0:
        raise ValueError(f"lam={lam!r}: the sampled mode is unstable already at x={lo}")
    for hi in grid[1:]:
        if excess(float(hi)) >= 0.0:
            return float(brentq(excess, lo, float(hi), xtol=1e-14, rtol=1e-14))
        lo = float(hi)
    raise ValueError(f"lam={lam!r}: no stability boundary found for x <= {grid[-1]}")


# ------------------------------------------------------------------------ step response


def step_overshoot_pct(derivative_on_error: bool) -> float:
    """Step overshoot (%) of the single-axis closed loop, independent of J and wn.

    PI-D (derivative on the measurement): ``T(s) = (3 s + 1)/(s + 1)^3`` (s in units of
    wn), overshoot ``5/e^3 = 24.9 %``. PID (derivative on the error):
    ``T(s) = (3 s^2 + 3 s + 1)/(s + 1)^3``, overshoot ``(sqrt 3 - 1) e^(sqrt 3 - 3)``
    = 20.6 %. Closed forms: each step response peaks where its derivative vanishes
    (tests/test_control_analysis.py checks both against ``control.step_info``).

    Args:
        derivative_on_error: True for PID (velocity feedforward on), False for PI-D.
    """
    if derivative_on_error:
        return 100.0 * (math.sqrt(3.0) - 1.0) * math.exp(math.sqrt(3.0) - 3.0)
    return 500.0 / math.e ** 3


# ------------------------------------------------------------------------------ report


class LoopReport(TypedDict):
    """The loop facts at one pose (:func:`loop_report`), JSON-ready (plain floats)."""

    #: the modal gains lam (dimensionless), descending
    modal_gain: list[float]
    #: the smallest damping ratio over the modes (dimensionless)
    coupled_zeta_min: float
    #: the sampled-loop boundary of wn T at lam_max, closed form (exact hold)
    sampled_boundary_wnT: float
    #: the same, found numerically with the plant's sub-steps
    sampled_boundary_numeric_wnT: float
    #: wn T of the loop (dimensionless)
    wnT: float
    #: the numeric boundary over wn T
    margin: float
    #: the gains: N m/rad, N m/(rad s), N m s/rad
    kp: list[float]
    ki: list[float]
    kd: list[float]
    #: the inertias the gains were placed on (kg m^2)
    j_eff: list[float]
    #: step overshoot of the single axis, PI-D and PID (%)
    step_overshoot_single_axis_pct: float
    step_overshoot_ff_pct: float


def loop_report(mass_matrix: ArrayLike, j_eff: ArrayLike, wn: float, rate_hz: float,
                substeps: int | None = None) -> LoopReport:
    """The loop facts (docs/original.md, "5.4 Loop facts") at one pose, JSON-ready (plain
    floats).

    Args:
        mass_matrix: (n, n) M(q) at the pose (kg m^2).
        j_eff: (n,) the inertias the gains were placed on (kg m^2).
        wn: the bandwidth (rad/s).
        rate_hz: the controller rate (Hz); the period is ``T = 1/rate_hz`` s.
        substeps: plant sub-steps per control period for the numeric boundary (``None``:
            exact hold).

    Returns:
        ``modal_gain`` (descending), ``coupled_zeta_min``, ``sampled_boundary_wnT``
        (closed form, exact hold, at lam_max), ``sampled_boundary_numeric_wnT`` (with
        ``substeps``), ``wnT``, ``margin`` (numeric boundary / wnT), ``kp``
        (N m/rad), ``ki`` (N m/(rad s)), ``kd`` (N m s/rad), ``j_eff`` (kg m^2),
        ``step_overshoot_single_axis_pct`` (PI-D) and ``step_overshoot_ff_pct`` (PID).

    Raises:
        ValueError: a bad input (see the functions used).
    """
    w = _positive("wn", wn)
    rate = _positive("rate_hz", rate_hz)
    j = _positive_array("j_eff", j_eff)
    lam = modal_gains(mass_matrix, j)
    kp, ki, kd = pole_placement_gains(j, w)
    wnt = w / rate
    lam_max = float(lam[0])
    numeric = sampled_boundary_numeric(lam_max, substeps)
    return {
        "modal_gain": [float(v) for v in lam],
        "coupled_zeta_min": coupled_zeta_min(lam),
        "sampled_boundary_wnT": sampled_boundary_wnT(lam_max),
        "sampled_boundary_numeric_wnT": numeric,
        "wnT": wnt,
        "margin": numeric / wnt,
        "kp": [float(v) for v in kp],
        "ki": [float(v) for v in ki],
        "kd": [float(v) for v in kd],
        "j_eff": [float(v) for v in j],
        "step_overshoot_single_axis_pct": step_overshoot_pct(False),
        "step_overshoot_ff_pct": step_overshoot_pct(True),
    }
