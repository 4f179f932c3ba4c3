"""One closed-loop run: the shared controller on any plant, tick by tick.

At every controller tick ``k`` the plant's state is measured (and logged), the controller
computes a torque, and the plant integrates ``substeps = period / dt`` steps with it held.
Every ``sample_every`` ticks the run is checked: a non-finite state, an engine warning or
a joint further than ``abort_error_rad`` from its reference ends it as *diverged* (the
log keeps what ran; nothing is NaN). The loop's verdict is then ``diverged``,
``saturated`` (a torque reached 0.999 of its limit) or ``ok`` (bounded and unsaturated).
That says nothing of accuracy: a drawing's verdict, which also judges the marking error
against the drawing's tolerance, is :func:`tattotronix.control.verdict.judge`'s.

Two paths run the same controller (docs/control.md, "The loop inside the engine"):

* ``engine``: where the plant can run the PID itself (MuJoCo's native ``pid`` actuator,
  :meth:`~tattotronix.plants.base.Plant.engine_pid`), one controller tick per plant step,
  for ``pid``, ``pid_g`` and ``pid_g_v``: the reference (and its rate, for ``pid_g_v``)
  is the control sequence, stepped in C a second of simulated time per call, and the log
  is read back from the engine's states. The checks fall at the same ticks.
* ``python``: the controller in Python every tick, for the rest (``computed_torque``, a
  controller slower than the plant, a plant without a native PID, a live viewer).

``loop="auto"`` picks the engine wherever it can; :attr:`Run.loop` says which ran.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import PlantConfig
from tattotronix.control.controller import Controller
from tattotronix.control.reference import Reference
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.plants.base import EnginePid, Plant

__all__ = ["LOOPS", "SATURATION", "Loop", "Run", "saturation", "simulate", "substeps_per_tick"]

Array = NDArray[np.float64]

#: (simulated seconds done, wall seconds so far) -> None
Progress = Callable[[float, float], None]

SATURATION = 0.999  # of the torque limit: "saturated" (docs/original.md, "5.5 Tracking error")

#: which path runs the controller: ``auto`` (the engine wherever it can), or one forced
Loop = Literal["auto", "engine", "python"]
LOOPS: tuple[Loop, ...] = ("auto", "engine", "python")


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
        verdict: the loop's verdict: ``ok`` (bounded and unsaturated: nothing about its
            accuracy, which :func:`tattotronix.control.verdict.judge` adds), ``saturated``
            or ``diverged``.
        reason: why it diverged or saturated ("" otherwise).
        wall_s: wall time of the loop, s.
        substeps: plant steps per tick.
        loop: the path that ran the controller: ``engine`` or ``python``.
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
    loop: str = "python"

    @property
    def stable(self) -> bool:
        """The loop stayed bounded to the end (it did not diverge)."""
        return self.verdict != "diverged"

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
        """JSON-ready; the same on every run of the same inputs (no wall times). The
        verdict is the loop's (a drawing's metrics replace it and its reason with the
        judged ones: :meth:`tattotronix.control.drawing.ClosedLoop.metrics`)."""
        return {"backend": self.backend, "verdict": self.verdict, "reason": self.reason,
                "stable": self.stable, "completed": self.completed, "sim_s": self.sim_s,
                "ticks": len(self.t), "substeps": self.substeps, "loop_path": self.loop,
                "peak_torque_nm": self.peak_torque_nm}


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
    err = float(np.max(np.abs(q - ref.q[min(k, ref.ticks - 1)])))
    return "" if err <= abort_error_rad else _too_far(err, ref, k, abort_error_rad)


def _too_far(err: float, ref: Reference, k: int, abort_error_rad: float) -> str:
    return (f"a joint is {err:.3g} rad from its reference at t = "
            f"{ref.t[min(k, ref.ticks - 1)]:.3f} s (abort at {abort_error_rad:g} rad)")


def _engine(plant: Plant, controller: Controller, sub: int, viewer: bool,
            loop: Loop) -> EnginePid | None:
    """The plant's engine running the controller, where it can (and ``loop`` allows)."""
    if loop not in LOOPS:
        raise TattotronixError(f"loop='{loop}': use one of {', '.join(LOOPS)}")
    spec = controller.engine_spec()
    engine = None
    if loop != "python" and sub == 1 and not viewer and spec is not None:
        engine = plant.engine_pid(spec)
    if engine is None and loop == "engine":
        why = ("the controller is slower than the plant" if sub != 1 else
               "a live viewer needs the Python loop" if viewer else
               f"{controller.structure.name} has no engine form" if spec is None else
               f"the {plant.backend} plant has no native PID")
        raise TattotronixError(f"loop='engine' cannot run here: {why}")
    return engine


def simulate(plant: Plant, controller: Controller, ref: Reference, *, sample_every: int,
             abort_error_rad: float = PlantConfig().abort_error_rad,
             progress: Progress | None = None,
             progress_every_s: float = 1.0, viewer: bool = False,
             loop: Loop = "auto") -> Run:
    """Run ``controller`` on ``plant`` along ``ref`` from the reference's first state.

    Args:
        plant: the plant (reset here).
        controller: the controller (bound to ``ref`` here).
        ref: the reference at the controller's ticks.
        sample_every: ticks between health checks (the error samples).
        abort_error_rad: a joint this far from its reference ends the run (diverged).
        progress: called every ``progress_every_s`` simulated seconds.
        viewer: refresh the plant's viewer at every check (real-time pacing).
        loop: ``auto`` (the engine wherever it can), ``engine`` or ``python``.

    Raises:
        TattotronixError: ``loop="engine"`` where the engine cannot run this controller.
    """
    sub = substeps_per_tick(ref.period_s, plant.dt)
    every = max(1, int(sample_every))
    report_every = max(every, int(round(progress_every_s / ref.period_s)))
    engine = _engine(plant, controller, sub, viewer, loop)
    controller.bind(ref, per_tick=engine is None)
    gc_was_on = gc.isenabled()
    gc.disable()  # the loop allocates short-lived lists only: no cycles to collect
    wall0 = time.perf_counter()
    try:
        if engine is None:
            k, reason, logs = _python_loop(plant, controller, ref, sub, every, report_every,
                                           abort_error_rad, progress, viewer, wall0)
        else:
            k, reason, logs = _engine_loop(engine, controller, ref, every, report_every,
                                           abort_error_rad, progress, wall0)
    finally:
        if gc_was_on:
            gc.enable()
    wall = time.perf_counter() - wall0
    q_log, qd_log, tau_log = logs
    tau_arr = tau_log[:k]
    tau_arr[~np.isfinite(tau_arr)] = 0.0
    completed = k == ref.ticks and not reason
    if reason:
        verdict = "diverged"
    else:
        reason = saturation(tau_arr, controller.torque_limit, ref.t,
                            controller.dynamics.joint_names)
        verdict = "saturated" if reason else "ok"
    qd_s = qd_log[: (k - 1) // every + 1 if k else 0]
    qd_s[~np.isfinite(qd_s)] = 0.0
    return Run(backend=plant.backend, t=ref.t[:k].copy(), q=q_log[:k], qd_samples=qd_s,
               sample_every=every, tau=tau_arr, ref=ref, completed=completed,
               verdict=verdict, reason=reason, wall_s=wall, substeps=sub,
               loop="python" if engine is None else "engine")


def saturation(tau: Array, limit: float | Array, t: Array, joints: Sequence[str],
               what: str = "its limit") -> str:
    """Why a run is saturated: the first tick at which a torque reached
    :data:`SATURATION` of its limit ("" if none did).

    Args:
        tau: (K, n) torques, N m. limit: the limit (scalar or (n,)), N m.
        t: the ticks' times, s. joints: the joints' names.
        what: names the limit (``its limit``, ``its servo's stall torque``).
    """
    lim = np.broadcast_to(np.asarray(limit, dtype=np.float64), tau.shape[1:])
    hit = np.abs(tau) >= SATURATION * lim
    if not hit.any():
        return ""
    tick, joint = (int(i) for i in np.argwhere(hit)[0])
    name = joints[joint] if joint < len(joints) else f"joint {joint}"
    return (f"the torque of {name} reached {what} ({float(lim[joint]):.3g} N m) at "
            f"t = {float(t[tick]):.3f} s")


#: (ticks that ran, why it stopped ("" if it did not), (q, qd at the samples, tau) logs)
_Outcome = tuple[int, str, tuple[Array, Array, Array]]


def _logs(n_ticks: int, n: int, every: int) -> tuple[Array, Array, Array]:
    return (np.empty((n_ticks, n)), np.empty(((n_ticks - 1) // every + 1, n)),
            np.zeros((n_ticks, n)))


def _finite_prefix(q_log: Array, k: int) -> int:
    """The ticks before the first logged state that is not finite (of the first ``k``)."""
    good = np.all(np.isfinite(q_log[:k]), axis=1)
    return k if good.all() else int(np.argmin(good))


def _python_loop(plant: Plant, controller: Controller, ref: Reference, sub: int, every: int,
                 report_every: int, abort_error_rad: float, progress: Progress | None,
                 viewer: bool, wall0: float) -> _Outcome:
    """The controller in Python, one torque per tick, checked every ``every`` ticks."""
    n_ticks = ref.ticks
    plant.reset(ref.q[0], ref.qd[0])
    q_log, qd_log, tau_log = _logs(n_ticks, plant.n, every)
    torque, apply, step = controller.torque, plant.apply, plant.step
    q, qd = plant.q, plant.qd  # live views, updated in place by every step
    reason = ""
    k = 0
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
            k = _finite_prefix(q_log, k)  # keep only the ticks whose logged state is finite
            break
        if viewer:
            plant.sync_viewer()
        if progress is not None and (k % report_every < every or k == n_ticks):
            progress(k * ref.period_s, time.perf_counter() - wall0)
    return k, reason, (q_log, qd_log, tau_log)


def _engine_loop(engine: EnginePid, controller: Controller, ref: Reference, every: int,
                 report_every: int, abort_error_rad: float, progress: Progress | None,
                 wall0: float) -> _Outcome:
    """The controller inside the engine, a stretch of ``report_every`` ticks per call
    (whole checks), checked at the same ticks as the Python loop."""
    n_ticks, n = ref.ticks, controller.n
    engine.reset(ref.q[0], ref.qd[0])
    q_log, qd_log, tau_log = _logs(n_ticks, n, every)
    v_ref = ref.qd if controller.derivative_on_error else np.zeros_like(ref.qd)
    chunk = report_every - report_every % every
    reason = ""
    k = 0
    while k < n_ticks:
        stop = min(k + chunk, n_ticks)
        q, qd, tau = engine.run(ref.q[k:stop], v_ref[k:stop])
        q_log[k:stop], tau_log[k:stop] = q, tau
        qd_log[k // every:(stop - 1) // every + 1] = qd[::every]
        # the Python loop's checks: after each `every` ticks, and at the very end
        ends = np.append(np.arange(k + every, stop, every), stop)
        q_end, _ = engine.state()
        q_at = np.vstack([q_log[ends[:-1]], q_end[None]])
        err = np.max(np.abs(q_at - ref.q[np.minimum(ends, n_ticks - 1)]), axis=1)
        bad = ~(np.all(np.isfinite(q_at), axis=1) & (err <= abort_error_rad))
        if bad.any() or not engine.healthy():
            # the first failing check, as the Python loop would have stopped there (an
            # engine warning with every check passed: the last check of the stretch)
            i = int(np.argmax(bad)) if bad.any() else len(ends) - 1
            k = int(ends[i])
            far = bool(bad.any() and np.all(np.isfinite(q_at[i])))
            reason = (_too_far(float(err[i]), ref, k, abort_error_rad) if far else
                      "the plant's state is not finite (the engine reported instability)")
            k = _finite_prefix(q_log, k)
            break
        k = stop
        if progress is not None:
            progress(k * ref.period_s, time.perf_counter() - wall0)
    return k, reason, (q_log, qd_log, tau_log)
