"""The verdict on a drawing's closed-loop run: did it draw what was planned, within the
drawing's tolerance? (docs/control.md, "Verdicts".)

The verdict, worst first:

* ``diverged``: the loop did not stay bounded (a state that is not finite, an engine
  warning, or a joint further than ``plant.abort_error_rad`` from its reference); the
  run stopped there;
* ``saturated``: a torque reached 0.999 of its limit (on the servo plant: a servo its
  stall torque); the loop left the range it was tuned for;
* ``out-of-tolerance``: the loop stayed bounded and under its limits, but while marking
  the tip strayed from the plan by more than the drawing's tolerance;
* ``ok``: none of these: bounded, unsaturated, and every marking sample within tolerance.

The tolerance is ``draw.tolerance_needle_widths`` of the needle's width
(``toolpath.needle_width_mm``): 0.5 of the 0.3 mm needle, 150 µm, by default. Within half
a width the drawn line still covers the centreline it was planned on; further off, it
visibly leaves its place. The marking error judged is the worst sampled tip error while
the needle is down (``marking_max_um``, entries included).

Stability and accuracy stay apart: ``stable`` says the loop stayed bounded (not
diverged), ``within_tolerance`` the accuracy (None where no marking sample ran). A score
that cannot be given is ``null`` with a ``*_reason`` beside it (:func:`unscored_ink`),
never a perfect one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from tattotronix.config.schema import DrawConfig, ToolpathConfig
from tattotronix.io.jsontypes import JsonDict

__all__ = ["VERDICTS", "Judgement", "Tolerance", "Verdict", "judge", "length_text"]

#: a drawing run's verdict
Verdict = Literal["ok", "out-of-tolerance", "saturated", "diverged"]
#: the verdicts, best first
VERDICTS: tuple[Verdict, ...] = ("ok", "out-of-tolerance", "saturated", "diverged")

#: lengths from here up print in mm, not µm
_MM_FROM_UM = 1000.0


def length_text(um: float | None, unit: str = "um") -> str:
    """A length given in µm, for a person: ``18.75 um`` below a millimetre, ``14.12 mm``
    from a millimetre up, ``-`` for None (``unit`` spells the micrometre: ``um`` in
    logs, ``µm`` in figures)."""
    if um is None:
        return "-"
    if abs(um) >= _MM_FROM_UM:
        return f"{um / 1e3:.2f} mm"
    return f"{um:.2f} {unit}"


@dataclass(frozen=True)
class Tolerance:
    """How far the tip may stray while marking.

    Attributes:
        widths: the tolerance in needle widths (``draw.tolerance_needle_widths``).
        needle_mm: the needle's width (``toolpath.needle_width_mm``), mm.
    """

    widths: float
    needle_mm: float

    @classmethod
    def from_settings(cls, draw: DrawConfig, toolpath: ToolpathConfig) -> Tolerance:
        """The configured tolerance: ``draw.tolerance_needle_widths`` of the needle
        (``toolpath.needle_width_mm``)."""
        return cls(float(draw.tolerance_needle_widths), float(toolpath.needle_width_mm))

    @property
    def um(self) -> float:
        """The tolerance, µm."""
        return self.widths * self.needle_mm * 1e3

    def text(self) -> str:
        """``150 um (draw.tolerance_needle_widths=0.5 of the 0.3 mm needle)``."""
        um = self.um
        size = f"{um / 1e3:.4g} mm" if um >= _MM_FROM_UM else f"{um:.4g} um"
        return (f"{size} (draw.tolerance_needle_widths={self.widths:g} of the "
                f"{self.needle_mm:g} mm needle)")


@dataclass(frozen=True)
class Judgement:
    """The verdict on a run, and what it rests on.

    Attributes:
        verdict: ``ok``, ``out-of-tolerance``, ``saturated`` or ``diverged``.
        reason: why it is not ``ok`` ("" when it is).
        stable: the loop stayed bounded to the end (not diverged).
        within_tolerance: the worst marking error is within the tolerance; None where no
            marking sample ran (or the run diverged, which leaves no error to judge).
        tolerance: the tolerance it was judged against.
        marking_max_um: the worst marking error judged, µm (None: none to judge).
    """

    verdict: Verdict
    reason: str
    stable: bool
    within_tolerance: bool | None
    tolerance: Tolerance
    marking_max_um: float | None

    @property
    def scores_ink(self) -> bool:
        """Whether the run's ink may be scored: the loop stayed bounded and unsaturated
        (an out-of-tolerance run's ink is scored: it shows how far off it is)."""
        return self.verdict in ("ok", "out-of-tolerance")

    def metrics(self) -> JsonDict:
        """``verdict``, ``reason``, ``stable``, ``within_tolerance``, ``tolerance_um``."""
        return {"verdict": self.verdict, "reason": self.reason, "stable": self.stable,
                "within_tolerance": self.within_tolerance, "tolerance_um": self.tolerance.um}

    def unscored_ink(self) -> str:
        """Why the run's ink is not scored ("" when it is)."""
        if self.scores_ink:
            return ""
        return f"not scored: the run {self.verdict}; {self.reason}"

    def warning(self, label: str, real_arm: bool = False) -> str:
        """The one line a user must not miss when the run is not ``ok`` ("" when it is).

        Args:
            label: ``emblem on servo``.
            real_arm: the run predicts the real arm (the servo plant).
        """
        if self.verdict == "ok":
            return ""
        if self.verdict == "out-of-tolerance":
            who = "the real arm will miss" if real_arm else "the simulated arm misses"
            return (f"WARNING: draw {label} is OUT OF TOLERANCE: {who} the drawing by up "
                    f"to {length_text(self.marking_max_um)} while marking, over the "
                    f"tolerance of {self.tolerance.text()}")
        return f"WARNING: draw {label} {self.verdict.upper()}: {self.reason}"


def judge(loop_verdict: str, loop_reason: str, marking_max_um: float | None,
          tolerance: Tolerance) -> Judgement:
    """The verdict on a run (module docstring).

    Args:
        loop_verdict: the loop's own (:attr:`tattotronix.control.simulate.Run.verdict`):
            ``ok``, ``saturated`` or ``diverged``.
        loop_reason: why the loop diverged or saturated.
        marking_max_um: the worst sampled tip error while marking, µm (None: no marking
            sample).
        tolerance: the drawing's tolerance.
    """
    if loop_verdict not in ("ok", "saturated", "diverged"):
        raise ValueError(f"not a loop verdict: {loop_verdict!r}")
    stable = loop_verdict != "diverged"
    within = (None if marking_max_um is None or not stable
              else bool(marking_max_um <= tolerance.um))
    if loop_verdict == "diverged":
        return Judgement("diverged", loop_reason, False, None, tolerance, None)
    if loop_verdict == "saturated":
        return Judgement("saturated", loop_reason, True, within, tolerance, marking_max_um)
    if within is False:
        reason = (f"the marking error reaches {length_text(marking_max_um)}, over the "
                  f"tolerance of {tolerance.text()}")
        return Judgement("out-of-tolerance", reason, True, False, tolerance, marking_max_um)
    return Judgement("ok", "", True, within, tolerance, marking_max_um)
