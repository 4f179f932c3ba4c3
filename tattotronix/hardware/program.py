"""The servo program: a trajectory compiled into PCA9685 counts, one row per servo frame.

Steps (``deploy`` stage; ``draw.py backend=arm`` compiles the same way):

1. Sample the trajectory's C1 Hermite reference at every frame, ``t_i = i / frame_hz``.
2. Clamp each joint to its range, then limit every frame-to-frame change to the joint's
   velocity limit times the frame period (so nothing is commanded faster than allowed).
3. Optionally, the servo corrections (``hardware.compensate``;
   :func:`tattotronix.hardware.servo_model.compensate`) move each frame's angle; with a
   lead, each joint's frames are sent sampled that much later on the trajectory (clamped
   to its end), so a servo that acts late acts on time.
4. Each servo's pulse: ``clamp(zero_us + us_per_rad q, min_us, max_us)`` (or the inverse
   of the calibration's measured fit, where it has one), rounded to the
   board's count (``(prescale + 1) / oscillator``, 4.88 us at 50 Hz), never outside the
   calibrated limits (:meth:`tattotronix.hardware.servos.Calibration.counts`).

Reported: frames, the largest count step per channel, and the quantisation error per
joint (the angle a servo is sent, from its count, against the commanded one) in degrees,
with the tip error it implies.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicHermiteSpline

from tattotronix.hardware.pca9685 import prescaler
from tattotronix.hardware.servos import Calibration
from tattotronix.io.artifacts import ServoProgramRecord
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import Chain

__all__ = ["ServoProgram", "compile_program", "count_period_us", "rate_clamp"]

Array = NDArray[np.float64]


def count_period_us(frame_hz: float, oscillator_hz: float) -> float:
    """One PCA9685 count, us: ``(prescale + 1) / oscillator`` (4.88 at 50 Hz, 25 MHz)."""
    return (prescaler(frame_hz, oscillator_hz) + 1) / oscillator_hz * 1e6


def rate_clamp(q: Array, start: ArrayLike, max_step: ArrayLike) -> tuple[Array, int]:
    """Limit every step of ``q`` (F, n) to ``max_step`` (n,) per frame, from ``start``.

    Returns:
        The clamped angles and how many frames were changed.
    """
    q = np.asarray(q, dtype=np.float64)
    n_frames, n = q.shape
    prev0 = np.broadcast_to(np.asarray(start, dtype=np.float64), (n,))
    step = np.broadcast_to(np.asarray(max_step, dtype=np.float64), (n,))
    out = q.copy()
    moved = np.zeros(n_frames, dtype=bool)
    # each joint on its own, in Python floats: the same IEEE arithmetic as a row at a
    # time in numpy, without numpy's cost per call (25 times faster on a whole drawing)
    for j in range(n):
        col = q[:, j]
        s = float(step[j])
        first = float(prev0[j])
        prev = first
        res = col.tolist()
        for i, x in enumerate(res):
            d = x - prev
            d = -s if d < -s else (s if d > s else d)
            prev = prev + d
            res[i] = prev
        out[:, j] = res
        moved |= np.abs(out[:, j] - col) > 1e-12
    return out, int(moved.sum())


@dataclass(frozen=True)
class ServoProgram:
    """Counts per channel for every frame.

    Attributes:
        t: (F,) frame times, s.
        q: (F, n) commanded joint angles after the range and rate clamps, rad.
        q_sent: (F, n) the angles the counts are made of (``q`` after the servo
            corrections; ``q`` itself when there are none), rad.
        counts: (F, C) off counts per channel (columns in ``channels`` order).
        channels: the driven channels.
        frame_hz: frames per second.
        count_us: one count, us.
        range_clamped: frames where a joint was clamped to its range.
        rate_clamped: frames where a joint was slowed to its rate limit.
    """

    t: Array
    q: Array
    counts: NDArray[np.int64]
    channels: tuple[int, ...]
    frame_hz: float
    count_us: float
    range_clamped: int
    rate_clamped: int
    q_sent: Array | None = None

    @property
    def frames(self) -> int:
        """Number of frames."""
        return len(self.t)

    def digest(self) -> str:
        """A hash of the counts: a resume must continue the same program."""
        h = hashlib.sha256(np.ascontiguousarray(self.counts).tobytes())
        h.update(repr((self.channels, self.frame_hz)).encode())
        return h.hexdigest()[:16]

    def record(self) -> ServoProgramRecord:
        """What the ``deploy`` stage stores (``deploy/<name>.npz``; the clamp counts are in
        its metrics)."""
        return ServoProgramRecord(t=self.t, q=self.q, counts=self.counts,
                                  channels=self.channels, frame_hz=self.frame_hz,
                                  count_us=self.count_us)

    def row(self, i: int) -> dict[int, int]:
        """``{channel: counts}`` of frame ``i``."""
        return dict(zip(self.channels, (int(c) for c in self.counts[i]), strict=True))

    def sent_angles(self, calib: Calibration) -> Array:
        """(F, n) the angles the counts stand for (servo A of each joint), rad."""
        return np.array([calib.positions(self.row(i), self.count_us)
                         for i in range(self.frames)]).reshape(self.q.shape)

    def metrics(self, calib: Calibration, chain: Chain) -> JsonDict:
        """Frames, count steps, quantisation per joint (deg: the counts' angles against
        the angles meant to be sent, corrections included) and the tip error it implies,
        and the largest servo correction per joint (deg: the angles sent against the
        plan's)."""
        steps = np.abs(np.diff(self.counts, axis=0)).max(axis=0) if self.frames > 1 else \
            np.zeros(len(self.channels), dtype=np.int64)
        sent = self.sent_angles(calib)
        meant = self.q if self.q_sent is None else self.q_sent
        quant = np.abs(sent - meant)
        tip, _ = chain.fk(meant)
        tip_sent, _ = chain.fk(sent)
        dev = np.linalg.norm(tip_sent - tip, axis=1) * 1e3
        names = calib.joint_names
        correction = np.abs(meant - self.q)
        return {
            "correction_deg": {n: float(np.degrees(correction[:, i].max()))
                               for i, n in enumerate(names)},
            "frames": self.frames,
            "frame_hz": self.frame_hz,
            "duration_s": self.frames / self.frame_hz,
            "count_us": self.count_us,
            "channels": list(self.channels),
            "max_count_step": {str(ch): int(s) for ch, s in zip(self.channels, steps,
                                                                strict=True)},
            "quantisation_deg": {n: float(np.degrees(quant[:, i].max()))
                                 for i, n in enumerate(names)},
            "quantisation_tip_mm_max": float(dev.max()),
            "quantisation_tip_mm_mean": float(dev.mean()),
            "range_clamped_frames": self.range_clamped,
            "rate_clamped_frames": self.rate_clamped,
        }


def compile_program(t: Array, q: Array, qd: Array, calib: Calibration, lower: ArrayLike,
                    upper: ArrayLike, velocity: ArrayLike,
                    adjust: Callable[[Array], Array] | None = None,
                    lead_s: ArrayLike | None = None) -> ServoProgram:
    """Compile a timed joint trajectory into the servo program (see the module docstring).

    Args:
        t, q, qd: the trajectory's point times (s), angles (rad) and rates (rad/s).
        calib: the servo calibration (board settings included).
        lower, upper: joint ranges, rad.
        velocity: joint velocity limits, rad/s.
        adjust: the servo corrections, (F, n) frame angles -> the angles to send.
        lead_s: (n,) how far ahead each joint's command is sampled, s (None: none).
    """
    frame_hz = float(calib.frame_hz)
    count_us = count_period_us(frame_hz, calib.oscillator_hz)
    n_frames = int(math.floor(float(t[-1]) * frame_hz + 1e-9)) + 1
    tf = np.arange(n_frames, dtype=np.float64) / frame_hz
    spline = CubicHermiteSpline(t, q, qd, axis=0)
    qf = spline(tf)
    lo, hi = np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64)
    range_clamped = int(np.any((qf < lo) | (qf > hi), axis=1).sum())
    qf = np.clip(qf, lo, hi)
    max_step = np.asarray(velocity, dtype=np.float64) / frame_hz
    qf, rate_clamped = rate_clamp(qf, qf[0], max_step)
    ahead = qf
    if lead_s is not None:
        lead = np.broadcast_to(np.asarray(lead_s, dtype=np.float64), (qf.shape[1],))
        end = float(t[-1])
        ahead = np.column_stack([spline(np.minimum(tf + lead[j], end))[:, j]
                                 for j in range(qf.shape[1])])
        ahead, _ = rate_clamp(np.clip(ahead, lo, hi), ahead[0], max_step)
    sent = ahead if adjust is None else adjust(ahead)
    channels = calib.channels()
    counts = calib.count_table(sent, count_us)
    return ServoProgram(t=tf, q=qf, counts=counts, channels=channels, frame_hz=frame_hz,
                        count_us=count_us, range_clamped=range_clamped,
                        rate_clamped=rate_clamped, q_sent=sent)
