"""The reference the controller follows, sampled at its ticks.

The trajectory gives ``q`` and ``qd`` at its points; between them the reference is the
C1 cubic Hermite through both (so ``qd_r`` is the derivative of ``q_r``, and ``qdd_r``
the derivative of ``qd_r``), evaluated at every controller tick ``t0 + k T``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicHermiteSpline

from tattotronix.control.tracking import busiest_window
from tattotronix.errors import TattotronixError

__all__ = ["Reference", "reference_at_ticks", "resolve_window"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Reference:
    """The reference at the controller's ticks.

    Attributes:
        t: (K,) tick times, s (trajectory time).
        q, qd, qdd: (K, n) reference angles (rad), rates (rad/s), accelerations (rad/s^2).
        period_s: the controller period, s.
    """

    t: Array
    q: Array
    qd: Array
    qdd: Array
    period_s: float

    @property
    def ticks(self) -> int:
        """Number of controller ticks."""
        return len(self.t)

    @property
    def duration_s(self) -> float:
        """Simulated time covered, s."""
        return self.ticks * self.period_s

    def middle_pose(self) -> Array:
        """The reference pose mid-way through (the default tuning pose), rad."""
        return self.q[self.ticks // 2].copy()


def resolve_window(window: object, t: Array, kind: NDArray[np.int8],
                   busiest_s: float = 12.0) -> tuple[float, float]:
    """``(start_s, end_s)`` of the stretch to run.

    Args:
        window: ``None`` (all), ``[start_s, length_s]``, ``[start_s]`` (to the end) or
            ``"busiest"`` (the 12 s window with the most needle entries: docs/original.md,
            "5.5 Tracking error").
        t: trajectory point times, s.
        kind: point kinds (0 travel, 1 mark, 2 approach).
        busiest_s: the length of the busiest window, s.

    Raises:
        TattotronixError: a malformed window or one outside the drawing.
    """
    end = float(t[-1])
    if window is None:
        return 0.0, end
    if isinstance(window, str):
        if window.strip().lower() != "busiest":
            raise TattotronixError(f"window={window!r}: give [start_s, length_s], "
                                   "[start_s] or busiest")
        start, length = busiest_window(t, kind, busiest_s)
        return start, min(start + length, end)
    try:
        vals = [float(v) for v in window]  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise TattotronixError(f"window={window!r}: give [start_s, length_s] in seconds, "
                               "[start_s] or busiest") from None
    if len(vals) not in (1, 2) or not all(np.isfinite(vals)):
        raise TattotronixError(f"window={window!r}: give [start_s, length_s] in seconds")
    start = vals[0]
    stop = end if len(vals) == 1 else start + vals[1]
    if not 0.0 <= start < end or stop <= start:
        raise TattotronixError(f"window={window!r} is outside the drawing (0 to {end:.2f} s) "
                               "or empty: start in [0, end) and a positive length")
    return start, min(stop, end)


def reference_at_ticks(t: Array, q: Array, qd: Array, period_s: float,
                       start_s: float = 0.0, end_s: float | None = None) -> Reference:
    """Sample the trajectory's Hermite interpolant at ``start_s + k period_s``.

    Args:
        t: (N,) strictly increasing point times, s.
        q, qd: (N, n) angles and rates at the points.
        period_s: controller period, s.
        start_s, end_s: the stretch (default: the whole trajectory).
    """
    if not period_s > 0:
        raise TattotronixError(f"controller period {period_s} s: the rate must be positive")
    end = float(t[-1]) if end_s is None else float(end_s)
    n_ticks = int(np.floor((end - start_s) / period_s + 1e-9)) + 1
    if n_ticks < 2:
        raise TattotronixError(f"the stretch {start_s:.3f}..{end:.3f} s is shorter than two "
                               f"controller periods ({period_s} s)")
    tk = start_s + period_s * np.arange(n_ticks, dtype=np.float64)
    tk[-1] = min(tk[-1], float(t[-1]))
    spline = CubicHermiteSpline(t, q, qd, axis=0)
    return Reference(t=tk, q=spline(tk), qd=spline(tk, 1), qdd=spline(tk, 2),
                     period_s=float(period_s))
