"""The joint controller, one implementation for every plant (docs/control.md, "The
controller"; the original's: docs/original.md, "5.2 Controller structure" and "5.3 Tuning
by pole placement").

Independent PID per joint on the joint torque, tuned by pole placement on the effective
inertia (all three poles at -wn)::

    Kp = 3 J wn^2,   Kd = 3 J wn,   Ki = J wn^3,   J = J_eff,i = 1 / (M^-1)_ii at tune_q

    tau = Kp e + Ki int(e) + Kd e_D + [G(q)] + [M(q) qdd_r + C(q, qd) qd]

``e = q_r - q``; the integral takes the new error *before* tau is computed; ``e_D`` is
``-qd`` (derivative on the measurement, "PI-D") unless the velocity feedforward is on,
when it is ``qd_r - qd`` ("PID"). Structures:

* ``pid``: no feedforward;
* ``pid_g``: gravity G(q) at the measured q;
* ``pid_g_v``: gravity, and the derivative acts on the error (velocity feedforward);
* ``computed_torque``: as ``pid_g_v``, plus M(q) qdd_r + C(q, qd) qd (one RNEA call).

The sum is clamped to the torque limit (after the feedforward) and held for one period
(zero-order hold). :meth:`Controller.torque` is the per-tick hot path: it works on plain
Python floats, which for five joints costs less than numpy's per-call overhead.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.config.schema import Structure
from tattotronix.control.analysis import pole_placement_gains
from tattotronix.control.dynamics import Dynamics
from tattotronix.control.reference import Reference
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.plants.base import PidSpec

__all__ = ["Controller", "Gains", "Structure", "structure_of"]

Array = NDArray[np.float64]


def structure_of(value: str | Enum) -> Structure:
    """The :class:`Structure` a config value names.

    Raises:
        TattotronixError: an unknown structure (the message lists the known ones).
    """
    name = value.name if isinstance(value, Enum) else str(value)
    try:
        return Structure[name]
    except KeyError:
        raise TattotronixError(
            f"unknown controller.structure '{name}': use one of "
            f"{', '.join(s.name for s in Structure)}") from None


@dataclass(frozen=True)
class Gains:
    """Per-joint PID gains from pole placement on J_eff.

    Attributes:
        kp: N m/rad. ki: N m/(rad s). kd: N m s/rad.
        j_eff: the effective inertias they were placed on, kg m^2.
        wn: the bandwidth, rad/s.
        tune_q: the pose J_eff was taken at, rad.
    """

    kp: Array
    ki: Array
    kd: Array
    j_eff: Array
    wn: float
    tune_q: Array

    @classmethod
    def pole_placement(cls, j_eff: ArrayLike, wn: float, tune_q: ArrayLike) -> Gains:
        """Kp = 3 J wn^2, Kd = 3 J wn, Ki = J wn^3 (all three poles at -wn).

        Raises:
            TattotronixError: ``wn`` or an inertia is not positive and finite.
        """
        j = np.asarray(j_eff, dtype=np.float64)
        if not (np.isfinite(wn) and wn > 0):
            raise TattotronixError(f"controller.wn={wn}: the bandwidth must be a positive "
                                   "number of rad/s")
        if not (np.all(np.isfinite(j)) and np.all(j > 0)):
            raise TattotronixError(f"effective inertia {j.tolist()} kg m^2 is not positive "
                                   "at the tuning pose: check controller.tune_q")
        kp, ki, kd = pole_placement_gains(j, wn)
        return cls(kp=kp, ki=ki, kd=kd, j_eff=j, wn=float(wn),
                   tune_q=np.asarray(tune_q, dtype=np.float64).copy())

    @classmethod
    def tuned_at(cls, dynamics: Dynamics, q: ArrayLike, wn: float) -> Gains:
        """Place the poles on J_eff(q) from the dynamics model."""
        q = np.asarray(q, dtype=np.float64)
        return cls.pole_placement(dynamics.effective_inertia(q), wn, q)

    def as_dict(self) -> JsonDict:
        """JSON-ready."""
        return {"kp": self.kp.tolist(), "ki": self.ki.tolist(), "kd": self.kd.tolist(),
                "j_eff": self.j_eff.tolist(), "wn": self.wn, "tune_q": self.tune_q.tolist()}


class Controller:
    """The shared joint controller (see the module docstring).

    Args:
        dynamics: the controller's model (gravity and computed-torque feedforward).
        gains: the PID gains.
        structure: which feedforward terms are on.
        rate_hz: the loop rate (one torque per period, held).
        torque_limit: per-joint limit, N m (scalar or (n,)).
    """

    def __init__(self, dynamics: Dynamics, gains: Gains, structure: Structure | str,
                 rate_hz: float, torque_limit: float | ArrayLike):
        if not (np.isfinite(rate_hz) and rate_hz > 0):
            raise TattotronixError(f"controller.rate_hz={rate_hz}: give a positive rate in Hz")
        lim = np.broadcast_to(np.asarray(torque_limit, dtype=np.float64), (dynamics.n,))
        if not (np.all(np.isfinite(lim)) and np.all(lim > 0)):
            raise TattotronixError(f"torque limit {lim.tolist()} N m: must be positive")
        self.dynamics = dynamics
        self.gains = gains
        self.structure = structure_of(structure)
        self.rate_hz = float(rate_hz)
        self.period_s = 1.0 / self.rate_hz
        self.torque_limit = lim.copy()
        self.n = dynamics.n
        self._ref: Reference | None = None
        # plain-float copies for the hot path (gains and limit are fixed for a controller)
        self._kp = gains.kp.tolist()
        self._kd = gains.kd.tolist()
        self._ki = gains.ki.tolist()
        self._lim = self.torque_limit.tolist()
        self._kq = (gains.kp + gains.ki * self.period_s).tolist()
        self._zeros = (0.0,) * self.n
        self._integral = [0.0] * self.n
        # per-tick constants, filled by bind()
        self._r: list[list[float]] = []
        self._c: list[list[float]] = []

    @property
    def derivative_on_error(self) -> bool:
        """True when the velocity feedforward is on (``pid_g_v``, ``computed_torque``)."""
        return self.structure in (Structure.pid_g_v, Structure.computed_torque)

    def engine_spec(self) -> PidSpec | None:
        """This controller as a PID an engine can run itself (``pid``, ``pid_g``,
        ``pid_g_v``; the gravity then is the plant's own, equal to this model's where the
        models agree), or None (``computed_torque`` needs the model every tick)."""
        if self.structure is Structure.computed_torque:
            return None
        g = self.gains
        return PidSpec(kp=g.kp.copy(), ki=g.ki.copy(), kd=g.kd.copy(),
                       limit=self.torque_limit.copy(),
                       gravity=self.structure is not Structure.pid)

    def bind(self, ref: Reference, per_tick: bool = True) -> None:
        """Follow ``ref`` from its first tick: reset the integral and, for :meth:`torque`
        (``per_tick``; the engine's loop needs none), precompute each tick's constants."""
        if abs(ref.period_s - self.period_s) > 1e-12 * self.period_s:
            raise TattotronixError(f"reference sampled every {ref.period_s} s, the controller "
                                   f"runs every {self.period_s} s")
        self._ref = ref
        self._r, self._c = [], []
        if per_tick:
            g = self.gains
            r = ref.q * self.period_s  # q_r T: the integral's reference part
            c = g.kp * ref.q + g.ki * r + (g.kd * ref.qd if self.derivative_on_error else 0.0)
            self._r = r.tolist()
            self._c = c.tolist()
        self.reset()

    def reset(self) -> None:
        """Zero the integral."""
        self._integral = [0.0] * self.n

    @property
    def integral(self) -> Array:
        """The integral of the error, rad s."""
        return np.asarray(self._integral)

    def torque(self, k: int, q: Array, qd: Array) -> list[float]:
        """The torque to hold over tick ``k`` (N m), from the measured ``q`` (rad) and ``qd``.

        Args:
            k: tick index into the bound reference.
            q, qd: float64 (n,) measured angles and rates (a plant's state views).
        """
        ql = q.tolist()
        vl = qd.tolist()
        s = self.structure
        if s is Structure.pid:
            ff: Sequence[float] = self._zeros
        elif s is Structure.computed_torque:
            assert self._ref is not None
            ff = self.dynamics.rnea_view(q, qd, self._ref.qdd[k]).tolist()
        else:
            ff = self.dynamics.gravity_view(q).tolist()
        # Ki I_new = Ki I_old + Ki T (q_r - q): the q_r part is folded into _c, the q part
        # into _kq = Kp + Ki T, so one pass gives tau from the old integral
        period = self.period_s
        old = self._integral
        self._integral = [i + r - period * x for i, r, x in zip(old, self._r[k], ql, strict=True)]
        lim = self._lim
        out = [c + ki * i - kq * x - kd * v + f for c, ki, i, kq, x, kd, v, f in
               zip(self._c[k], self._ki, old, self._kq, ql, self._kd, vl, ff, strict=True)]
        return [m if t > m else (-m if t < -m else t) for t, m in zip(out, lim, strict=True)]

    def summary(self) -> JsonDict:
        """JSON-ready description of the controller."""
        return {"structure": self.structure.name, "rate_hz": self.rate_hz,
                "torque_limit_nm": self.torque_limit.tolist(), **self.gains.as_dict()}
