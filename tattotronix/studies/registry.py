"""Every closed-loop study by name, and what the ``studies`` stage makes of them all.

Each study is one module holding its :class:`~tattotronix.studies.base.ClosedLoopStudy`
(``STUDY``); this is the one list of them (a study's own stage imports only its module).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.studies import approach, control, rate, resample, timelaw
from tattotronix.studies.base import ClosedLoopStudy

__all__ = ["STUDIES", "study_figures", "study_summary"]

#: study name -> study, in the order the figures are drawn and summarised
STUDIES: dict[str, ClosedLoopStudy] = {
    m.STUDY.name: m.STUDY for m in (control, approach, resample, rate, timelaw)}


def study_figures(data: Path, name: str, folder: Path,
                  tmp: Callable[[Path], Path] | None = None) -> dict[str, Path]:
    """Draw every closed-loop study's figure that has cases on ``name``.

    Args:
        data: the data folder.
        name: the artwork.
        folder: where the PNGs go (``<study>.png``).
        tmp: maps a target path to the path to write (``Outputs.tmp_path``); default:
            write the target itself.

    Returns:
        study -> the target path written.
    """
    written: dict[str, Path] = {}
    for study in STUDIES.values():
        cases = study.load_cases(data, name)
        if not cases:
            continue
        target = folder / f"{study.name}.png"
        study.figure(cases, tmp(target) if tmp is not None else target, name)
        written[study.name] = target
    return written


def study_summary(data: Path, name: str) -> JsonDict:
    """What each closed-loop study with cases on ``name`` concludes (study -> its
    :meth:`~tattotronix.studies.base.ClosedLoopStudy.summary`; JSON-ready)."""
    out: JsonDict = {}
    for study in STUDIES.values():
        cases = study.load_cases(data, name)
        if cases:
            out[study.name] = study.summary(cases)
    return out


def study_curves(data: Path, name: str) -> dict[str, list[dict[str, JsonValue]]]:
    """Each closed-loop study's curve on ``name`` (study -> its
    :meth:`~tattotronix.studies.base.ClosedLoopStudy.curve` rows), for ``dvc plots``."""
    out: dict[str, list[dict[str, JsonValue]]] = {}
    for study in STUDIES.values():
        cases = study.load_cases(data, name)
        if cases:
            out[study.name] = study.curve(cases)
    return out


def format_summary(conclusions: JsonValue) -> str:
    """A study's conclusions in one line a person reads: ``key value`` pairs, numbers to
    four significant digits (the metrics file keeps them whole)."""
    if isinstance(conclusions, dict):
        return ", ".join(f"{k} ({format_summary(v)})" if isinstance(v, dict)
                         else f"{k} {format_summary(v)}" for k, v in conclusions.items())
    if isinstance(conclusions, list):
        return "[" + ", ".join(format_summary(v) for v in conclusions) + "]"
    if isinstance(conclusions, float):
        return f"{conclusions:.4g}"
    return str(conclusions)
