"""What the real arm is about to draw, shown before anything reaches the bus.

``draw.py backend=arm`` prints :meth:`Preview.text` first, as a plotter's driver does: the
duration, the needle entries, the drawing's box on the panel (and whether it fits), and
the start and end poses. ``preview=true`` stops there and writes :meth:`Preview.figure`,
the tip's path on the panel from the servo program's own poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tattotronix.control.tracking import entry_times
from tattotronix.kinematics import Chain
from tattotronix.path.kinds import MARK
from tattotronix.plotting import pyplot

__all__ = ["Preview", "preview_of"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Preview:
    """The plan of a run on the arm, in the terms its user checks before inking.

    Attributes:
        name: the drawing.
        frames, frame_hz: the servo program's length and rate.
        entries: needle entries (marking stretches).
        tip_mm: the commanded tip on the panel plane, (N, 2) mm from ``toolpath.panel_origin``.
        marking: which of those points mark.
        panel_mm: the panel's corners on the same plane, (x0, y0, x1, y1) mm.
        start_deg, end_deg: the first and last commanded poses, deg.
    """

    name: str
    frames: int
    frame_hz: float
    entries: int
    tip_mm: Array
    marking: NDArray[np.bool_]
    panel_mm: tuple[float, float, float, float]
    start_deg: Array
    end_deg: Array

    @property
    def duration_s(self) -> float:
        """How long the program runs, s."""
        return self.frames / self.frame_hz

    @property
    def box_mm(self) -> tuple[float, float, float, float]:
        """The inked box (x0, y0, x1, y1), mm on the panel plane (the whole path where
        nothing marks)."""
        pts = self.tip_mm[self.marking] if self.marking.any() else self.tip_mm
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    @property
    def fits(self) -> bool:
        """Whether the inked box lies on the panel."""
        x0, y0, x1, y1 = self.box_mm
        p0, q0, p1, q1 = self.panel_mm
        return x0 >= p0 and y0 >= q0 and x1 <= p1 and y1 <= q1

    def duration_text(self, decimals: int) -> str:
        """The duration as ``10 min 50.4 s`` (seconds to ``decimals`` places)."""
        minutes, seconds = divmod(self.duration_s, 60.0)
        width = 3 + decimals if decimals else 2
        return f"{int(minutes)} min {seconds:0{width}.{decimals}f} s"

    def text(self) -> str:
        """The plan in one block, as the arm's run prints it before the bus is opened."""
        x0, y0, x1, y1 = self.box_mm

        def pose(q: Array) -> str:
            return "[" + ", ".join(f"{v:.1f}" for v in q) + "] deg"

        lines = [
            f"plan for the arm: {self.name}",
            f"  duration      {self.duration_text(1)} ({self.frames} frames at "
            f"{self.frame_hz:g} Hz)",
            f"  needle entries {self.entries}",
            f"  inked box     x {x0:.1f} .. {x1:.1f} mm, y {y0:.1f} .. {y1:.1f} mm "
            f"({x1 - x0:.1f} x {y1 - y0:.1f} mm) from the panel origin; "
            + ("on the panel" if self.fits else "NOT within the panel"),
            f"  start pose    {pose(self.start_deg)}",
            f"  end pose      {pose(self.end_deg)}",
        ]
        return "\n".join(lines)

    def figure(self, path: Path) -> Path:
        """Draw the tip's path on the panel: marking black, travel grey, the inked box
        dashed, the start and the end marked; mm on both axes."""
        plt = pyplot()
        from matplotlib.patches import Rectangle

        fig, ax = plt.subplots(figsize=(10.0, 5.2))
        p0, q0, p1, q1 = self.panel_mm
        ax.add_patch(Rectangle((p0, q0), p1 - p0, q1 - q0, fill=True, fc="#f4efe6",
                               ec="#8a7f6a", lw=1.0, label="panel"))
        xy = self.tip_mm
        travel = np.where(self.marking[:, None], np.nan, xy)
        mark = np.where(self.marking[:, None], xy, np.nan)
        ax.plot(travel[:, 0], travel[:, 1], color="0.6", lw=0.6, label="travel (needle up)")
        ax.plot(mark[:, 0], mark[:, 1], color="black", lw=1.0, label="marking")
        x0, y0, x1, y1 = self.box_mm
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="tab:red",
                               ls="--", lw=1.0, label=f"inked box {x1 - x0:.1f} x "
                               f"{y1 - y0:.1f} mm"))
        ax.plot(*xy[0], "o", color="tab:green", ms=7, label="start")
        ax.plot(*xy[-1], "s", color="tab:blue", ms=6, label="end")
        ax.set_aspect("equal")
        ax.set_xlabel("x on the panel (mm)")
        ax.set_ylabel("y on the panel (mm)")
        ax.set_title(f"{self.name} on the arm: {self.duration_text(0)}, "
                     f"{self.entries} needle entries"
                     + ("" if self.fits else " - NOT within the panel"))
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9)
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        return path


def preview_of(name: str, t: Array, q: Array, kind: NDArray[np.int8], frames: int,
               frame_hz: float, chain: Chain, panel_origin_m: Array,
               panel_centre_m: Array, panel_size_m: Array) -> Preview:
    """The preview of a drawing (``t``, ``q``, ``kind``: its points) compiled into
    ``frames`` servo frames at ``frame_hz``."""
    q = np.asarray(q, dtype=np.float64)
    tip, _ = chain.fk(q)
    origin = np.asarray(panel_origin_m, dtype=np.float64)
    tip_mm = (tip[:, :2] - origin[:2]) * 1e3
    centre = (np.asarray(panel_centre_m, dtype=np.float64)[:2] - origin[:2]) * 1e3
    half = np.asarray(panel_size_m, dtype=np.float64)[:2] * 1e3 / 2
    return Preview(
        name=name, frames=int(frames), frame_hz=float(frame_hz),
        entries=int(len(entry_times(np.asarray(t, dtype=np.float64), kind))),
        tip_mm=tip_mm, marking=np.asarray(kind) == MARK,
        panel_mm=(float(centre[0] - half[0]), float(centre[1] - half[1]),
                  float(centre[0] + half[0]), float(centre[1] + half[1])),
        start_deg=np.degrees(q[0]), end_deg=np.degrees(q[-1]))
