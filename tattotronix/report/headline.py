"""The headline figures: the few numbers per drawing that ``dvc metrics show`` and
``dvc exp show`` show (README, "Metrics and experiments").

DVC lists every key of every file declared as a metric, so the pipeline declares only
these; the full metrics stay in their files under ``data/metrics/`` (git-tracked, read
with ``dvc metrics show <file>``, ``dvc metrics diff --targets data/metrics`` or as plain
JSON).

Per drawing, in the order ``dvc exp show`` shows them (:data:`KEYS`):

======== ==================================================================================
entries  needle entries (``trajectory/<name>.json`` ``entries``)
time_s   the drawing's duration, s (``trajectory`` ``duration_s``)
cycle    the duration over the marking-only time (``trajectory`` ``cycle_over_marking``)
max_um   the worst tip error while marking, simulated on MuJoCo at the controller
         defaults, µm (``runs/<name>-mujoco.json`` ``marking_max_um``)
mean_um  the settled mean tip error, µm (``runs`` ``settled_mean_um``)
bleed    the share of the simulated ink outside the artwork (``runs``
         ``artwork.bleed_share``)
cover    the share of the artwork the simulated ink covers (``runs`` ``artwork.coverage``)
servo_mm the worst marking deviation the servo plant predicts for the arm as built, mm
         (the servo study's case ``built``: ``servo/<name>/built.json``
         ``whole.marking_max_um``); only the study artwork has a servo study
======== ==================================================================================

Numbers are rounded to three significant digits (the duration to 0.1 s), so the table is
narrow and equal results give equal bytes; a figure the source does not have (the ink of
a run that diverged, the servo prediction of a drawing without a servo study) is ``null``,
which DVC shows as ``-``.

The ``headline`` stage writes two views of the same numbers:

* ``data/metrics/headline.json``: the study artwork's figures, flat (:data:`KEYS`): the one
  file declared as a DVC metric. ``dvc exp show`` makes a column of every key of every
  metrics file, so one row of eight short keys per experiment is what fits a terminal;
  the other drawings' would each need eight more columns.
* ``data/metrics/headline/<key>.json``: one figure of every drawing (``{"emblem": ...,
  "lineart": ...}``), so ``dvc metrics show data/metrics/headline`` prints a figure per
  row and a drawing per column within 80 columns, and ``dvc metrics diff
  --targets data/metrics/headline`` compares every drawing.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.io.outputs import Outputs

__all__ = [
    "FILE",
    "FOLDER",
    "KEYS",
    "SERVO_CASE",
    "drawing_headline",
    "drawings",
    "format_headline",
    "headline_tables",
    "write_headline",
]

#: the headline keys, in the order ``dvc exp show`` shows them
KEYS = ("entries", "time_s", "cycle", "max_um", "mean_um", "bleed", "cover", "servo_mm")
#: the study artwork's figures (the DVC metric), under ``<paths.data>/metrics``
FILE = "headline.json"
#: one file per key, every drawing in it, under ``<paths.data>/metrics``
FOLDER = "headline"
#: the servo study's case for the servos as mounted, uncorrected
#: (``tattotronix.studies.servo``; ``tests/test_headline.py`` holds the two equal)
SERVO_CASE = "built"


def _missing(path: Path, stage: str) -> TattotronixError:
    return TattotronixError(f"missing input {path}: run the '{stage}' stage first "
                            f"(dvc repro {stage})")


def _load(path: Path, stage: str) -> dict[str, object]:
    if not path.is_file():
        raise _missing(path, stage)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise TattotronixError(f"{path}: not a readable metrics file ({exc}): run the "
                               f"'{stage}' stage again (dvc repro {stage})") from None
    if not isinstance(doc, dict):
        raise TattotronixError(f"{path}: not a JSON object: run the '{stage}' stage again "
                               f"(dvc repro {stage})")
    return doc


def _number(doc: object, *keys: str) -> float | None:
    """``doc[k0][k1]...`` as a finite number, else None."""
    for key in keys:
        if not isinstance(doc, dict) or key not in doc:
            return None
        doc = doc[key]
    if isinstance(doc, bool) or not isinstance(doc, int | float) or not math.isfinite(doc):
        return None
    return float(doc)


def _sig(value: float | None, digits: int = 3) -> float | None:
    """``value`` to ``digits`` significant digits (a float: ``88177.0`` -> ``88200.0``)."""
    return None if value is None else float(f"{value:.{digits}g}")


def drawings(metrics: Path) -> list[str]:
    """The drawings the pipeline planned: one per ``trajectory/<name>.json``, sorted."""
    folder = metrics / "trajectory"
    if not folder.is_dir():
        raise _missing(folder, "trajectory")
    return sorted(p.stem for p in folder.glob("*.json"))


def drawing_headline(metrics: Path, name: str) -> JsonDict:
    """The headline figures of one drawing (:data:`KEYS`), from the metrics files under
    ``metrics`` (``<paths.data>/metrics``).

    Raises:
        TattotronixError: the drawing's trajectory or simulated run has no metrics file
            (naming the stage to run), or one that does not parse.
    """
    traj = _load(metrics / "trajectory" / f"{name}.json", f"trajectory@{name}")
    run = _load(metrics / "runs" / f"{name}-mujoco.json", f"simulate@{name}")
    servo_file = metrics / "servo" / name / f"{SERVO_CASE}.json"
    servo = _load(servo_file, "servo") if servo_file.is_file() else {}
    entries = _number(traj, "entries")
    duration = _number(traj, "duration_s")
    max_mm = _number(servo, "whole", "marking_max_um")
    out: JsonDict = {
        "entries": None if entries is None else int(entries),
        "time_s": None if duration is None else round(duration, 1),
        "cycle": _sig(_number(traj, "cycle_over_marking")),
        "max_um": _sig(_number(run, "marking_max_um")),
        "mean_um": _sig(_number(run, "settled_mean_um")),
        "bleed": _sig(_number(run, "artwork", "bleed_share")),
        "cover": _sig(_number(run, "artwork", "coverage")),
        "servo_mm": _sig(None if max_mm is None else max_mm / 1e3),
    }
    assert tuple(out) == KEYS
    return out


def headline_tables(metrics: Path, study: str) -> tuple[JsonDict, dict[str, JsonDict]]:
    """The study artwork's headline (``headline.json``) and, per key, every drawing's
    figure (``headline/<key>.json``).

    Raises:
        TattotronixError: the study artwork has no trajectory, or a drawing with a
            trajectory has no simulated run.
    """
    names = drawings(metrics)
    if study not in names:
        raise _missing(metrics / "trajectory" / f"{study}.json", f"trajectory@{study}")
    every = {name: drawing_headline(metrics, name) for name in names}
    per_key: dict[str, JsonDict] = {key: {n: every[n][key] for n in names} for key in KEYS}
    return every[study], per_key


def _dumps(doc: JsonDict) -> str:
    # the keys in their own order (dvc exp show keeps a file's order); no sort_keys
    return json.dumps(doc, indent=2) + "\n"


def write_headline(out: Outputs, study: str) -> JsonDict:
    """Stage ``headline.json`` and ``headline/<key>.json`` (see the module docstring) from
    the metrics under ``out.input("metrics")``; return the study artwork's figures."""
    study_figures, per_key = headline_tables(out.input("metrics"), study)
    out.write_text(out.path("metrics", FILE), _dumps(study_figures))
    for key, row in per_key.items():
        out.write_text(out.path("metrics", FOLDER, f"{key}.json"), _dumps(row))
    return study_figures


def _length(um: JsonValue) -> str:
    """A tip error for a person: µm, or mm above a millimetre."""
    if not isinstance(um, int | float):
        return "-"
    return f"{um / 1e3:.3g} mm" if um >= 1e3 else f"{um:.3g} µm"


def format_headline(name: str, h: JsonDict) -> str:
    """One line: ``emblem: 80 entries, 650.4 s (cycle 1.21), marking max 18.7 µm, settled
    mean 1.1 µm, bleed 0.238 %, cover 55.8 %, servos 18.6 mm``."""
    def pct(x: JsonValue) -> str:
        return f"{100 * x:.3g} %" if isinstance(x, int | float) else "-"

    servo = h.get("servo_mm")
    return (f"{name}: {h.get('entries', '-')} entries, {h.get('time_s', '-')} s (cycle "
            f"{h.get('cycle', '-')}), marking max {_length(h.get('max_um'))}, settled mean "
            f"{_length(h.get('mean_um'))}, bleed {pct(h.get('bleed'))}, cover "
            f"{pct(h.get('cover'))}, servos "
            f"{_length(1e3 * servo) if isinstance(servo, int | float) else '-'}")
