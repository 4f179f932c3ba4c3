"""One closed-loop run: the shared controller on any plant, tick by tick.

At every controller tick ``k`` the plant's state is measured (and logged), the controller
computes a torque, and the plant integrates ``substeps = period / dt`` steps with it held.
Every ``sample_every`` ticks the run is checked: a non-finite state, an engine warning or
a joint further than ``abort_error_rad`` from its reference ends it as *diverged* (the
log keeps what ran; nothing is NaN). The verdict is then ``diverged``, ``saturated`` (the
torque reached 0.999 of its limit) or ``ok``.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import PlantConfig
from tattotronix.control.controller import Controller
from tattotronix.control.reference import Reference
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.plants.base import Plant

__all__ = ["Run", "simulate", "substeps_per_tick"]

Array = NDArray[np.float64]

#: (simulated seconds done, wall seconds so far) -> None
Progress = Callable[[float, float], None]

SATURATION = 0.999  # of the torque limit: "saturated" (docs/original.md, "5.5 Tracking error")


@dataclass(frozen=True)
class Run:
    """What a closed-loop run did.

    Attributes:
        backend: the plant.
        t: (K,) tick times that ran, s (trajectory time).
        q: (K, n) measured angles at the ticks, rad.
        qd_samples: measured rates at every ``sample_every``-th tick, rad/s.
        sample_every: ticks between samples.
        tau: (K, n) torque held over each tick, N m.
        ref: the reference (all ticks, also those not run).
        completed: whether every tick ran.
        verdict: ``ok``, ``saturated`` or ``diverged``.
        reason: why it diverged ("" otherwise).
        wall_s: wall time of the loop, s.
        substeps: plant steps per tick.
    """

    backend: str
    t: Array
    q: Array
    qd_samples: Array
    sample_every: int
    tau: Array
    ref: Reference
    completed: bool
    verdict: str
    reason: str
    wall_s: float
    substeps: int

    @property
    def sim_s(self) -> float:
        """Simulated time, s."""
        return len(self.t) * self.ref.period_s

    @property
    def realtime_factor(self) -> float:
        """Simulated over wall time."""
        return self.sim_s / self.wall_s if self.wall_s > 0 else float("inf")

    @property
    def peak_torque_nm(self) -> float:
        """max over ticks and joints of |tau|, N m."""
        return float(np.abs(self.tau).max()) if len(self.tau) else 0.0

    def timings(self) -> dict[str, float]:
        """Wall time of the loop and the real-time factor (they vary from run to run, so
        they never go into a metrics file)."""
        return {"wall_s": self.wall_s, "realtime_factor": self.realtime_factor}

    def summary(self) -> JsonDict:
        """JSON-ready; the same on every run of the same inputs (no wall times)."""
        return {"backend": self.backend, "verdict": self.verdict, "reason": self.reason,
                "completed": self.completed, "sim_s": self.sim_s, "ticks": len(self.t),
                "substeps": self.substeps, "peak_torque_nm": self.peak_torque_nm}


def substeps_per_tick(period_s: float, dt_s: float) -> int:
    """Plant steps per controller tick.

    Raises:
        TattotronixError: the controller period is not a whole number of plant steps.
    """
    n = round(period_s / dt_s)
    if n < 1 or abs(n * dt_s - period_s) > 1e-9 * period_s:
        raise TattotronixError(
            f"the controller period {period_s * 1e3:g} ms is not a whole number of plant "
            f"steps of {dt_s * 1e3:g} ms: choose controller.rate_hz and plant.dt_s so that "
            "rate_hz * dt_s = 1/N")
    return n


def _check(plant: Plant, q: Array, ref: Reference, k: int, abort_error_rad: float) -> str:
    """Why the run must stop after tick ``k`` ("" if it may go on)."""
    if not plant.healthy():
        return "the plant's state is not finite (the engine reported instability)"
    i = min(k, ref.ticks - 1)
    err = float(np.max(np.abs(q - ref.q[i])))
    if not err <= abort_error_rad:
        return (f"a joint is {err:.3g} rad from its reference at t = {ref.t[i]:.3f} s "
                f"(abort at {abort_error_rad:g} rad)")
    return ""


def simulate(plant: Plant, controller: Controller, ref: Reference, *, sample_every: int,
             abort_error_rad: float = PlantConfig().abort_error_rad,
             progress: Progress | None = None,
             progress_every_s: float = 1.0, viewer: bool = False) -> Run:
    """Run ``controller`` on ``plant`` along ``ref`` from the reference's first state.

    Args:
        plant: the plant (reset here).
        controller: the controller (bound to ``ref`` here).
        ref: the reference at the controller's ticks.
        sample_every: ticks between health checks (the error samples).
        abort_error_rad: a joint this far from its reference ends the run (diverged).
        progress: called every ``progress_every_s`` simulated seconds.
        viewer: refresh the plant's viewer at every check (real-time pacing).
    """
    n_ticks, n = ref.ticks, plant.n
    sub = substeps_per_tick(ref.period_s, plant.dt)
    every = max(1, int(sample_every))
    controller.bind(ref)
    plant.reset(ref.q[0], ref.qd[0])
    q_log = np.empty((n_ticks, n))
    tau_log = np.zeros((n_ticks, n))
    qd_log = np.empty(((n_ticks - 1) // every + 1, n))  # rates at the samples only
    torque, apply, step = controller.torque, plant.apply, plant.step
    q, qd = plant.q, plant.qd  # live views, updated in place by every step
    report_every = max(every, int(round(progress_every_s / ref.period_s)))
    reason = ""
    k = 0
    gc_was_on = gc.isenabled()
    gc.disable()  # the loop allocates short-lived lists only: no cycles to collect
    wall0 = time.perf_counter()
    try:
        while k < n_ticks:
            stop = min(k + every, n_ticks)
            qd_log[k // every] = qd
            for j in range(k, stop):
                q_log[j] = q
                tau = torque(j, q, qd)
                tau_log[j] = tau
                apply(tau)
                step(sub)
            k = stop
            reason = _check(plant, q, ref, k, abort_error_rad)
            if reason:
                # keep only the ticks whose logged state is finite
                good = np.all(np.isfinite(q_log[:k]), axis=1)
                k = k if good.all() else int(np.argmin(good))
                break
            if viewer:
                plant.sync_viewer()
            if progress is not None and (k % report_every < every or k == n_ticks):
                progress(k * ref.period_s, time.perf_counter() - wall0)
    finally:
        if gc_was_on:
            gc.enable()
    wall = time.perf_counter() - wall0
    tau_arr = tau_log[:k]
    tau_arr[~np.isfinite(tau_arr)] = 0.0
    completed = k == n_ticks and not reason
    lim = controller.torque_limit
    if reason:
        verdict = "diverged"
    elif len(tau_arr) and np.any(np.abs(tau_arr) >= SATURATION * lim):
        verdict = "saturated"
    else:
        verdict = "ok"
    qd_s = qd_log[: (k - 1) // every + 1 if k else 0]
    qd_s[~np.isfinite(qd_s)] = 0.0
    return Run(backend=plant.backend, t=ref.t[:k].copy(), q=q_log[:k], qd_samples=qd_s,
               sample_every=every, tau=tau_arr, ref=ref, completed=completed,
               verdict=verdict, reason=reason, wall_s=wall, substeps=sub)
