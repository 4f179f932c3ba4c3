"""Toolpath parameters, checked once, with the derived costs the ordering uses.

The values come from the config (``toolpath``, ``mask.min_region_mm2`` and
``robot.panel.size``); this module holds no defaults of its own, so the YAML and the
schema stay the one source of truth. Everything here is in panel millimetres (the names
say ``_mm``) and seconds, except the arm-frame panel origin, which is in metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tattotronix.config.schema import MaskConfig, MaskMethod, PanelConfig, ToolpathConfig
from tattotronix.errors import TattotronixError

__all__ = ["ToolpathParams"]


@dataclass(frozen=True)
class ToolpathParams:
    """Everything the toolpath library needs, validated.

    Attributes:
        pitch_mm: hatch spacing (distance between fill scanlines), mm.
        needle_width_mm: the needle's ink line width, mm.
        compensate: run outlines and fill half a needle width inside the artwork's edge,
            and draw parts narrower than ``line_max_mm`` along their centreline
            (:mod:`tattotronix.path.inset`); False: the original's strokes.
        line_max_mm: parts narrower than this are line art (0: none), mm.
        lines_only: every part is line art, drawn along its centreline however wide (with
            ``compensate``): the edge bands of a photograph (``mask.method=edges``).
        fill_style: ``hatch``, ``cross`` (a second hatch at 90 degrees), ``concentric``
            (rings parallel to the outline) or ``solid`` (a hatch at the needle's width).
        fill_angle_deg: the hatch's angle from the x axis, degrees (anticlockwise).
        step_mm: arc-length resampling step along strokes, mm.
        clearance_mm: needle height above the panel surface for travel, mm.
        plunge_mm: marking depth below the surface, mm.
        approach_mm: last part of the plunge done at the marking feed, mm.
        min_loop_px: traced loops with fewer pixels are dropped.
        feed_mark_mm_s: marking and approach feed, mm/s.
        feed_travel_mm_s: travel feed (including vertical lifts), mm/s.
        lift_s: extra fixed cost per needle entry in the ordering objective, s.
        outlines_first: within a region, draw every outline before any fill row.
        min_region_mm2: ink regions smaller than this are dropped, mm^2.
        panel_size_mm: (width, height) of the panel, mm.
        panel_origin_m: arm-frame point (m) where the drawing centre lands on the surface.
    """

    pitch_mm: float
    step_mm: float
    clearance_mm: float
    plunge_mm: float
    approach_mm: float
    min_loop_px: int
    feed_mark_mm_s: float
    feed_travel_mm_s: float
    lift_s: float
    outlines_first: bool
    min_region_mm2: float
    panel_size_mm: tuple[float, float]
    panel_origin_m: tuple[float, float, float]
    fill_style: str = "hatch"
    fill_angle_deg: float = 0.0
    needle_width_mm: float = 0.3
    compensate: bool = False
    line_max_mm: float = 0.6
    lines_only: bool = False

    def __post_init__(self) -> None:
        positive = {
            "toolpath.pitch_mm": (self.pitch_mm, "the hatch spacing, e.g. 1.2"),
            "toolpath.step_mm": (self.step_mm, "the resampling step, e.g. 0.15"),
            "toolpath.feed_mark_mm_s": (self.feed_mark_mm_s, "the marking feed, e.g. 6"),
            "toolpath.feed_travel_mm_s": (self.feed_travel_mm_s, "the travel feed, e.g. 60"),
            "toolpath.needle_width_mm": (self.needle_width_mm, "the ink line width, e.g. 0.3"),
        }
        for key, (value, hint) in positive.items():
            if not (math.isfinite(value) and value > 0):
                raise TattotronixError(f"{key} must be > 0 and finite (got {value}): set {hint}")
        for key, value in {
            "toolpath.clearance_mm": self.clearance_mm,
            "toolpath.plunge_mm": self.plunge_mm,
            "toolpath.approach_mm": self.approach_mm,
            "toolpath.lift_s": self.lift_s,
            "mask.min_region_mm2": self.min_region_mm2,
            "toolpath.line_max_mm": self.line_max_mm,
        }.items():
            if not (math.isfinite(value) and value >= 0):
                raise TattotronixError(f"{key} must be >= 0 and finite (got {value})")
        if self.approach_mm > self.clearance_mm + self.plunge_mm:
            raise TattotronixError(
                f"toolpath.approach_mm ({self.approach_mm}) exceeds the whole plunge "
                f"(clearance_mm + plunge_mm = {self.clearance_mm + self.plunge_mm}): "
                "lower approach_mm or raise clearance_mm"
            )
        if self.fill_style == "concentric" and not self.compensate:
            raise TattotronixError(
                "toolpath.fill_style=concentric traces rings inside the compensated outline: "
                "set toolpath.compensate=true, or choose fill_style hatch, cross or solid")
        if self.min_loop_px < 1:
            raise TattotronixError(f"toolpath.min_loop_px must be >= 1 (got {self.min_loop_px})")
        if min(self.panel_size_mm) <= 0:
            raise TattotronixError(f"robot.panel.size must be > 0 (got {self.panel_size_mm} mm)")

    @classmethod
    def from_settings(cls, toolpath: ToolpathConfig, mask: MaskConfig,
                    panel: PanelConfig) -> ToolpathParams:
        """Build from the ``toolpath`` and ``mask`` settings and ``robot.panel``.

        Args:
            toolpath: the ``toolpath`` settings.
            mask: the ``mask`` settings (``min_region_mm2``, and ``method``: the edges of
                a photograph are line art).
            panel: ``robot.panel`` (only the width and height are read).
        """
        return cls(
            pitch_mm=float(toolpath.pitch_mm),
            step_mm=float(toolpath.step_mm),
            clearance_mm=float(toolpath.clearance_mm),
            plunge_mm=float(toolpath.plunge_mm),
            approach_mm=float(toolpath.approach_mm),
            min_loop_px=int(toolpath.min_loop_px),
            feed_mark_mm_s=float(toolpath.feed_mark_mm_s),
            feed_travel_mm_s=float(toolpath.feed_travel_mm_s),
            lift_s=float(toolpath.lift_s),
            outlines_first=bool(toolpath.outlines_first),
            min_region_mm2=float(mask.min_region_mm2),
            panel_size_mm=panel.size_mm,
            panel_origin_m=(
                float(toolpath.panel_origin[0]),
                float(toolpath.panel_origin[1]),
                float(toolpath.panel_origin[2]),
            ),
            fill_style=toolpath.fill_style.name,
            fill_angle_deg=float(toolpath.fill_angle_deg),
            needle_width_mm=float(toolpath.needle_width_mm),
            compensate=bool(toolpath.compensate),
            line_max_mm=float(toolpath.line_max_mm),
            lines_only=mask.method is MaskMethod.edges,
        )

    @property
    def fill_pitch_mm(self) -> float:
        """The fill's spacing: the needle's width for ``solid``, else ``pitch_mm``."""
        return self.needle_width_mm if self.fill_style == "solid" else self.pitch_mm

    @property
    def mark_z_mm(self) -> float:
        """Height of a marking point relative to the surface, mm (negative: in the work)."""
        return -self.plunge_mm

    @property
    def approach_z_mm(self) -> float:
        """Height where the slow approach starts, mm."""
        return -self.plunge_mm + self.approach_mm

    @property
    def entry_cost_s(self) -> float:
        """Time one needle entry adds over a straight travel move at clearance, s.

        Retract from the marking depth to clearance and descend to the approach start at
        the travel feed, the approach at the marking feed, plus ``lift_s``.
        """
        vertical = (self.clearance_mm + self.plunge_mm) + (self.clearance_mm - self.approach_z_mm)
        return (
            vertical / self.feed_travel_mm_s + self.approach_mm / self.feed_mark_mm_s + self.lift_s
        )

    @property
    def drag_max_mm(self) -> float:
        """Longest gap worth crossing with the needle down (on ink), mm.

        Dragging ``d`` mm costs ``d / feed_mark``; lifting costs ``entry_cost_s +
        d / feed_travel``. Beyond the break-even length a lift is faster.
        """
        slower = 1.0 / self.feed_mark_mm_s - 1.0 / self.feed_travel_mm_s
        return math.inf if slower <= 0 else self.entry_cost_s / slower
