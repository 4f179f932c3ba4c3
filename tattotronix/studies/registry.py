"""Every closed-loop study by name, and what the ``studies`` stage makes of them all.

Each study is one module holding its :class:`~tattotronix.studies.base.ClosedLoopStudy`
(``STUDY``); this is the one list of them (a study's own stage imports only its module).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.studies import approach, control, rate, resample, servo, timelaw
from tattotronix.studies.base import Cases, ClosedLoopStudy

__all__ = ["STUDIES", "Loaded", "format_summary", "load_studies", "study_curves",
           "study_figures", "study_summary"]

#: study name -> study, in the order the figures are drawn and summarised
STUDIES: dict[str, ClosedLoopStudy] = {
    m.STUDY.name: m.STUDY for m in (control, approach, resample, rate, timelaw, servo)}


#: each study with cases on one artwork: study name -> (the study, its cases)
Loaded = dict[str, tuple[ClosedLoopStudy, Cases]]


def load_studies(data: Path, name: str) -> Loaded:
    """Read the cases of every closed-loop study on ``name`` once (those with none are
    left out), for :func:`study_figures`, :func:`study_summary` and :func:`study_curves`.

    Args:
        data: the data folder.
        name: the artwork.
    """
    loaded: Loaded = {}
    for study in STUDIES.values():
        cases = study.load_cases(data, name)
        if cases:
            loaded[study.name] = (study, cases)
    return loaded


def study_figures(loaded: Loaded, name: str, folder: Path,
                  tmp: Callable[[Path], Path] | None = None) -> dict[str, Path]:
    """Draw each loaded study's figure.

    Args:
        loaded: :func:`load_studies`.
        name: the artwork (the figures' titles).
        folder: where the PNGs go (``<study>.png``).
        tmp: maps a target path to the path to write (``Outputs.tmp_path``); default:
            write the target itself.

    Returns:
        study -> the target path written.
    """
    written: dict[str, Path] = {}
    for study, cases in loaded.values():
        target = folder / f"{study.name}.png"
        study.figure(cases, tmp(target) if tmp is not None else target, name)
        written[study.name] = target
    return written


def study_summary(loaded: Loaded) -> JsonDict:
    """What each loaded study concludes (study -> its
    :meth:`~tattotronix.studies.base.ClosedLoopStudy.summary`; JSON-ready)."""
    return {study.name: study.summary(cases) for study, cases in loaded.values()}


def study_curves(loaded: Loaded) -> dict[str, list[dict[str, JsonValue]]]:
    """Each loaded study's curve (study -> its
    :meth:`~tattotronix.studies.base.ClosedLoopStudy.curve` rows), for ``dvc plots``."""
    return {study.name: study.curve(cases) for study, cases in loaded.values()}


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
