"""Every npz a stage writes and another reads: its keys, its path, the stage that makes it.

Each artifact has one :class:`ArtifactSpec` (the relative path under ``paths.data``, the
stage that writes it, the keys in writing order and the dtype each is stored as) and one
record: a frozen dataclass holding its arrays, written by ``record.save(file, provenance)``
and read by ``Record.load(file)``. Nothing else in the project names these keys or spells
these paths out; domain modules convert their own classes to and from the records.

==================  =========================================  ==========  =================
record              path under ``paths.data``                  stage       keys
==================  =========================================  ==========  =================
ToolpathRecord      ``toolpath/<name>.npz``                    toolpath    uvz_mm, kind,
                                                                           xyz_m, stroke,
                                                                           t_s, stroke_kind,
                                                                           stroke_region,
                                                                           stroke_width_mm
IkRecord            ``ik/<name>.npz``                          ik          joints, q, tcp,
                                                                           residual, uvz_mm,
                                                                           xyz_m, kind,
                                                                           stroke
TrajectoryRecord    ``trajectories/<name>.npz``                trajectory  joints, t, q, qd,
                                                                           qdd, kind, marked,
                                                                           tcp
RunLogRecord        ``runs/<name>-<backend>/log.npz``          simulate    joints, t, q, qd,
                                                                           tau, q_ref,
                                                                           qd_ref, tip,
                                                                           tip_ref, error_m,
                                                                           down, settled
ServoProgramRecord  ``deploy/<name>.npz``                      deploy      t, q, counts,
                                                                           channels,
                                                                           frame_hz, count_us
StudySeriesRecord   ``studies/<study>/<name>/<case>.npz``      <study>     the study's own
                    (``studies/actuator/<name>.npz``)          (actuator)
==================  =========================================  ==========  =================

Every file also holds ``provenance``: a JSON string (:func:`make_provenance`) with the
resolved config, its SHA-256 (``config_sha256``), the code version and the SHA-256 of each
input file. Files load with ``allow_pickle=False``. A reader refuses a missing, truncated or
foreign file with a :class:`~tattotronix.errors.TattotronixError` naming the file and the
stage that writes it.

This module imports nothing of the project beyond ``tattotronix.errors`` and
``tattotronix.io``.
"""

from __future__ import annotations

import json
import string
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.errors import StageInputMissing, TattotronixError
from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.io.npz import READ_ERRORS, save_npz
from tattotronix.io.provenance import (
    PROVENANCE_KEY,
    code_version,
    plain_config,
    provenance_json,
)

__all__ = [
    "ACTUATOR_SERIES",
    "IK",
    "PROVENANCE_KEY",
    "RUN_LOG",
    "SERVO_PROGRAM",
    "STUDY_SERIES",
    "TOOLPATH",
    "TRAJECTORY",
    "ArtifactSpec",
    "IkRecord",
    "RunLogRecord",
    "ServoProgramRecord",
    "StudySeriesRecord",
    "ToolpathRecord",
    "TrajectoryRecord",
    "make_provenance",
    "run_dir",
    "run_label",
]


#: dtype kinds each stored dtype may be read back as (old files, hand-made inputs)
_NUMERIC = "biuf"


def make_provenance(cfg: object, inputs: Mapping[str, str | Path],
                    code: str | None = None, roots: Sequence[str | Path] = ()) -> str:
    """The provenance JSON of an artifact made from ``cfg`` and the files ``inputs``.

    Args:
        cfg: the stage's config: a mapping of plain values, an OmegaConf ``DictConfig`` or
            a config dataclass (:func:`tattotronix.io.provenance.plain_config`).
        inputs: role -> file read (``{"ik": ..., "urdf": ...}``); each is hashed.
        code: the code version; :func:`tattotronix.io.provenance.code_version` if None.
        roots: the data folders the inputs were read from (an input under one is recorded
            relative to it; :meth:`tattotronix.io.outputs.Outputs.provenance` passes them).
    """
    return provenance_json(plain_config(cfg), inputs,
                           code_version() if code is None else code, roots)


def _check_provenance(text: str) -> str:
    try:
        prov = json.loads(text)
    except ValueError as exc:
        raise TattotronixError(f"provenance is not JSON ({exc})") from None
    missing = [k for k in ("config_sha256", "code_version", "inputs")
               if not isinstance(prov, dict) or k not in prov]
    if missing:
        raise TattotronixError(f"provenance lacks {', '.join(missing)}: build it with "
                               "tattotronix.io.artifacts.make_provenance")
    return text


def _fields_of(pattern: str) -> list[str]:
    return [f for _, f, _, _ in string.Formatter().parse(pattern) if f]


def run_label(name: str, backend: str, suffix: str = "") -> str:
    """The folder name of a run under ``runs/``: ``<name>-<backend><suffix>``."""
    return f"{name}-{backend}{suffix}"


def run_dir(data: str | Path, label: str) -> Path:
    """A run's folder under ``paths.data`` (``runs/<label>``): the log, ink images, and
    on the arm the I2C and pose logs."""
    return RUN_LOG.path(data, label=label).parent


@dataclass(frozen=True)
class ArtifactSpec:
    """Where an artifact lives, who writes it and what it holds.

    Attributes:
        kind: what it is, for messages ("toolpath", "IK path", ...).
        pattern: its path under ``paths.data``, ``/``-separated, with ``{fields}``.
        stage: the stage that writes it (may hold ``{fields}``, e.g. ``{study}``).
        keys: the array keys in writing order, ``provenance`` excluded (empty for a study
            series, whose keys are the study's own).
        dtypes: key -> the dtype it is stored as (``str`` for names); a key not listed is
            stored as given.
        command: how to run the stage by hand, when it is not ``python stages/<stage>.py``
            (may hold ``{fields}``).
    """

    kind: str
    pattern: str
    stage: str
    keys: tuple[str, ...]
    dtypes: Mapping[str, str] = field(default_factory=dict)
    command: str = ""

    def path(self, data: str | Path, **where: str) -> Path:
        """The artifact's file under ``data`` (``paths.data``)."""
        return Path(data).joinpath(*self.pattern.format(**where).split("/"))

    def find(self, data: str | Path, **where: str) -> list[Path]:
        """The stored files under ``data`` whose fields match ``where`` (a field not
        given matches anything), sorted."""
        fields_ = {k: where.get(k, "*") for k in _fields_of(self.pattern)}
        return sorted(Path(data).glob(self.pattern.format(**fields_)))

    def stage_of(self, **where: str) -> str:
        """The stage that writes the artifact at ``where``."""
        return self.stage.format(**where)

    def hint(self, **where: str) -> str:
        """``the 'ik' stage`` (with how to run it by hand when that is not obvious)."""
        try:
            text = f"the '{self.stage_of(**where)}' stage"
        except KeyError:
            text = f"the stage that writes {self.pattern}"
        if self.command:
            try:
                text += f" ({self.command.format(**where)})"
            except KeyError:
                pass
        return text

    def require(self, data: str | Path, **where: str) -> Path:
        """The artifact's file if it exists, else stop naming the stage that writes it."""
        file = self.path(data, **where)
        if not file.exists():
            raise self.missing(file, where)
        return file

    def missing(self, file: str | Path,
                where: Mapping[str, str] | None = None) -> TattotronixError:
        """The error for an absent file: run the stage that writes it."""
        where = where or {}
        if self.command:
            return TattotronixError(f"missing input {file}: run {self.hint(**where)} first"
                                    " (or dvc repro)")
        try:
            return StageInputMissing(Path(file), self.stage_of(**where))
        except KeyError:
            return TattotronixError(f"missing input {file}: run {self.hint(**where)} first")

    def refuse(self, file: str | Path, why: str,
               where: Mapping[str, str] | None = None) -> TattotronixError:
        """The error for an unreadable file: what is wrong and which stage to re-run
        (``where``: the path's fields, which may name the stage)."""
        return TattotronixError(f"cannot read {file} ({why}): re-run "
                                f"{self.hint(**(where or {}))}")

    def write(self, file: str | Path, arrays: Mapping[str, ArrayLike], provenance: str) -> None:
        """Write ``arrays`` (every key of the spec) and the provenance, compressed.

        Raises:
            TattotronixError: a key is missing or unknown, or the provenance is not
                :func:`make_provenance` JSON.
        """
        _check_provenance(provenance)
        if self.keys:
            missing = [k for k in self.keys if k not in arrays]
            extra = [k for k in arrays if k not in self.keys]
            if missing or extra:
                raise TattotronixError(f"{self.kind}: missing {missing}, unknown {extra}")
        if PROVENANCE_KEY in arrays:
            raise TattotronixError(f"{self.kind}: '{PROVENANCE_KEY}' is reserved")
        out: dict[str, Any] = {}
        for key, value in arrays.items():
            dtype = self.dtypes.get(key)
            out[key] = (np.array(value, dtype=np.str_) if dtype == "str"
                        else np.asarray(value) if dtype is None
                        else np.asarray(value).astype(dtype))
        out[PROVENANCE_KEY] = np.array(provenance, dtype=np.str_)
        save_npz(file, out)

    def read(self, file: str | Path, keys: Sequence[str] | None = None,
             where: Mapping[str, str] | None = None,
             ) -> tuple[dict[str, NDArray[np.generic]], JsonDict]:
        """Every array of the file (the spec's keys, or ``keys``) and the parsed provenance.

        Args:
            file: the npz.
            keys: the keys required (default: the spec's); with an empty spec, every key
                the file holds is read.
            where: the path's fields, for the stage named in a refusal (a study series
                names its study's stage).

        Raises:
            TattotronixError: the file is missing a key, is truncated or is not an npz;
                the message names the file and the stage that writes it.
        """
        want = tuple(self.keys if keys is None else keys)
        try:
            loaded = np.load(file, allow_pickle=False)
            if not isinstance(loaded, np.lib.npyio.NpzFile):
                raise self.refuse(file, "not an npz archive", where)
            with loaded as z:
                missing = [k for k in (*want, PROVENANCE_KEY) if k not in z.files]
                if missing:
                    raise self.refuse(file, "missing key" + ("s " if len(missing) > 1
                                                             else " ")
                                      + ", ".join(repr(k) for k in missing), where)
                names = want or tuple(k for k in z.files if k != PROVENANCE_KEY)
                arrays = {k: z[k] for k in names}
                prov_text = str(z[PROVENANCE_KEY])
        except TattotronixError:
            raise
        except FileNotFoundError:
            raise self.missing(file, where) from None
        except READ_ERRORS as exc:
            raise self.refuse(file, f"{type(exc).__name__}: {exc}", where) from None
        for key, arr in arrays.items():
            dtype = self.dtypes.get(key)
            if dtype == "str" and arr.dtype.kind != "U":
                raise self.refuse(file, f"key {key!r} holds {arr.dtype}, not names", where)
            if dtype not in (None, "str") and arr.dtype.kind not in _NUMERIC:
                raise self.refuse(file, f"key {key!r} holds {arr.dtype}, not numbers", where)
        try:
            prov = json.loads(prov_text)
        except ValueError:
            prov = None
        if not isinstance(prov, dict):
            raise self.refuse(file, "its provenance is not a JSON object", where)
        return arrays, prov


R = TypeVar("R", bound="_Record")


@dataclass(frozen=True)
class _Record:
    """Arrays named as the spec's keys (names as a tuple of str), then ``provenance``."""

    SPEC: ClassVar[ArtifactSpec]

    def arrays(self) -> dict[str, Any]:
        """The arrays to store, by key: the spec's keys (a subclass's own fields, such as a
        planned trajectory's, are not stored), else every field but the provenance."""
        keys = self.SPEC.keys or [f.name for f in fields(self) if f.name != PROVENANCE_KEY]
        return {k: getattr(self, k) for k in keys}

    def save(self, file: str | Path, provenance: str) -> None:
        """Write the artifact to ``file`` (an ``.npz`` path; e.g. ``Outputs.tmp_path``)
        with ``provenance`` (:func:`make_provenance`)."""
        self.SPEC.write(file, self.arrays(), provenance)

    @classmethod
    def _decode(cls, arrays: dict[str, NDArray[Any]]) -> dict[str, Any]:
        out: dict[str, Any] = dict(arrays)
        if "joints" in out:
            out["joints"] = tuple(str(j) for j in out["joints"])
        return out

    @classmethod
    def load(cls: type[R], file: str | Path) -> R:
        """Read the artifact (see :meth:`ArtifactSpec.read` for what is refused)."""
        arrays, prov = cls.SPEC.read(file)
        return cls._build(arrays, prov)

    @classmethod
    def _build(cls: type[R], arrays: dict[str, NDArray[Any]], prov: dict[str, Any]) -> R:
        kwargs: dict[str, Any] = {**cls._decode(arrays), PROVENANCE_KEY: prov}
        return cls(**kwargs)

    @classmethod
    def path(cls, data: str | Path, **where: str) -> Path:
        """The artifact's file under ``data`` (``paths.data``)."""
        return cls.SPEC.path(data, **where)

    @classmethod
    def require(cls, data: str | Path, **where: str) -> Path:
        """The artifact's file, or a refusal naming the stage that writes it."""
        return cls.SPEC.require(data, **where)


Float = NDArray[np.float64]

TOOLPATH = ArtifactSpec(
    "toolpath", "toolpath/{name}.npz", "toolpath",
    ("uvz_mm", "kind", "xyz_m", "stroke", "t_s", "stroke_kind", "stroke_region",
     "stroke_width_mm"),
    {"uvz_mm": "float64", "kind": "int8", "xyz_m": "float64", "t_s": "float64",
     "stroke": "int32", "stroke_kind": "int8", "stroke_region": "int32",
     "stroke_width_mm": "float64"})

IK = ArtifactSpec(
    "IK path", "ik/{name}.npz", "ik",
    ("joints", "q", "tcp", "residual", "uvz_mm", "xyz_m", "kind", "stroke"),
    {"joints": "str", "q": "float64", "tcp": "float64", "residual": "float64",
     "uvz_mm": "float64", "xyz_m": "float64", "kind": "int8", "stroke": "int32"})

TRAJECTORY = ArtifactSpec(
    "trajectory", "trajectories/{name}.npz", "trajectory",
    ("joints", "t", "q", "qd", "qdd", "kind", "marked", "tcp"),
    {"joints": "str", "t": "float64", "q": "float64", "qd": "float64", "qdd": "float64",
     "kind": "int8", "marked": "bool", "tcp": "float64"})

RUN_LOG = ArtifactSpec(
    "run log", "runs/{label}/log.npz", "simulate",
    ("joints", "t", "q", "qd", "tau", "q_ref", "qd_ref", "tip", "tip_ref", "error_m", "down",
     "settled"),
    {"joints": "str", "t": "float64", "q": "float64", "qd": "float64", "tau": "float64",
     "q_ref": "float64", "qd_ref": "float64", "tip": "float64", "tip_ref": "float64",
     "error_m": "float64", "down": "bool", "settled": "bool"},
    command="python stages/draw.py art={name} backend={backend} window=null")

SERVO_PROGRAM = ArtifactSpec(
    "servo program", "deploy/{name}.npz", "deploy",
    ("t", "q", "counts", "channels", "frame_hz", "count_us"),
    {"t": "float64", "q": "float64", "counts": "int64", "channels": "int64",
     "frame_hz": "float64", "count_us": "float64"})

#: a closed-loop study's series of one case (``stages/<study>.py``): its keys are the study's
STUDY_SERIES = ArtifactSpec("study series", "studies/{study}/{name}/{case}.npz", "{study}", ())

#: the actuator study's series of one artwork (``stages/actuator.py``)
ACTUATOR_SERIES = ArtifactSpec("actuator series", "studies/actuator/{name}.npz", "actuator",
                               ())


@dataclass(frozen=True)
class ToolpathRecord(_Record):
    """``toolpath/<name>.npz``, the ``toolpath`` stage's ordered needle path.

    Attributes:
        uvz_mm: (N, 3) panel coordinates, mm (z relative to the surface).
        kind: (N,) int8 point kinds: 0 travel, 1 mark, 2 approach.
        xyz_m: (N, 3) the points in the arm frame, m.
        stroke: (N,) int32, the stroke of each point (its place in the drawing order).
        t_s: (N,) the toolpath's own timing, s.
        stroke_kind: per drawn stroke, its kind (int8).
        stroke_region: per drawn stroke, its ink region (int32).
        stroke_width_mm: per drawn stroke, a line's designed width, mm (NaN for a stroke
            that is not a line along a centreline).
        provenance: the parsed provenance (empty before saving).
    """

    SPEC: ClassVar[ArtifactSpec] = TOOLPATH

    uvz_mm: Float
    kind: NDArray[np.int8]
    xyz_m: Float
    stroke: NDArray[np.int32]
    t_s: Float
    stroke_kind: NDArray[np.int8]
    stroke_region: NDArray[np.int32]
    stroke_width_mm: Float
    provenance: Mapping[str, JsonValue] = field(default_factory=dict)


@dataclass(frozen=True)
class IkRecord(_Record):
    """``ik/<name>.npz``, the ``ik`` stage's joint angles for every toolpath point.

    Attributes:
        joints: joint names, base outward.
        q: (N, n) joint angles, rad.
        tcp: (N, 3) the FK tip of ``q``, m.
        residual: (N,) the solver's residual per point.
        uvz_mm, xyz_m, kind, stroke: the toolpath's (:class:`ToolpathRecord`).
        provenance: the parsed provenance.
    """

    SPEC: ClassVar[ArtifactSpec] = IK

    joints: tuple[str, ...]
    q: Float
    tcp: Float
    residual: Float
    uvz_mm: Float
    xyz_m: Float
    kind: NDArray[np.int8]
    stroke: NDArray[np.int32]
    provenance: Mapping[str, JsonValue] = field(default_factory=dict)


@dataclass(frozen=True)
class TrajectoryRecord(_Record):
    """``trajectories/<name>.npz``, the ``trajectory`` stage's timed path.

    Attributes:
        joints: joint names.
        t: (N,) s; q, qd, qdd: (N, n) rad, rad/s, rad/s^2.
        kind: (N,) int8 point kinds; marked: (N,) bool, the segment ending here marks.
        tcp: (N, 3) the FK tip, m.
        provenance: the parsed provenance.
    """

    SPEC: ClassVar[ArtifactSpec] = TRAJECTORY

    joints: tuple[str, ...]
    t: Float
    q: Float
    qd: Float
    qdd: Float
    kind: NDArray[np.int8]
    marked: NDArray[np.bool_]
    tcp: Float
    provenance: Mapping[str, JsonValue] = field(default_factory=dict)

    @classmethod
    def load(cls, file: str | Path) -> TrajectoryRecord:
        """Read the trajectory, refusing one no arm could follow (:meth:`problem`): every
        reader (the collision check, deploy, the simulations, the arm and its preview)
        loads it here.

        Raises:
            TattotronixError: the file is unreadable, or holds an impossible trajectory;
                the message names the file, what is wrong and the 'trajectory' stage.
        """
        arrays, prov = cls.SPEC.read(file)
        rec = cls._build(arrays, prov)
        problem = rec.problem()
        if problem:
            raise cls.SPEC.refuse(file, problem)
        return rec

    def problem(self) -> str:
        """What makes the trajectory impossible, or "": times that are not finite and
        strictly increasing, angles, rates or tip positions that are not finite numbers,
        or arrays whose lengths disagree."""
        t = self.t
        if t.ndim != 1 or len(t) < 1:
            return f"time 't' must be a list of samples (got shape {t.shape})"
        n_t, n_j = len(t), len(self.joints)
        shapes = {"q": (n_t, n_j), "qd": (n_t, n_j), "qdd": (n_t, n_j), "kind": (n_t,),
                  "marked": (n_t,), "tcp": (n_t, 3)}
        for key, shape in shapes.items():
            have = np.shape(getattr(self, key))
            if have != shape:
                return (f"'{key}' has shape {have}, not {shape} ({n_t} samples of 't', "
                        f"{n_j} joints)")
        for key in ("t", "q", "qd", "qdd", "tcp"):
            bad = np.flatnonzero(~np.isfinite(np.asarray(getattr(self, key))).reshape(n_t, -1)
                                 .all(axis=1))
            if len(bad):
                return (f"'{key}' is not finite (NaN or inf) at {len(bad)} sample(s), the "
                        f"first at sample {bad[0]} (t = {t[bad[0]]:g} s)")
        back = np.flatnonzero(np.diff(t) <= 0)
        if len(back):
            i = int(back[0])
            return (f"time 't' is not strictly increasing: sample {i + 1} is at "
                    f"{t[i + 1]:.9g} s, after {t[i]:.9g} s ({len(back)} such step(s))")
        return ""


@dataclass(frozen=True)
class RunLogRecord(_Record):
    """``runs/<name>-<backend>/log.npz``, a closed-loop run's samples (the ``simulate``
    stage, ``python stages/draw.py``).

    Attributes:
        joints: joint names.
        t: (K,) sample times, s; q, qd, tau: (K, n) measured angles, rates, torques.
        q_ref, qd_ref: (K, n) the reference.
        tip, tip_ref: (K, 3) the FK tip of ``q`` and of ``q_ref``, m.
        error_m: (K,) the tracking error, m; down, settled: (K,) bool.
        provenance: the parsed provenance.
    """

    SPEC: ClassVar[ArtifactSpec] = RUN_LOG

    joints: tuple[str, ...]
    t: Float
    q: Float
    qd: Float
    tau: Float
    q_ref: Float
    qd_ref: Float
    tip: Float
    tip_ref: Float
    error_m: Float
    down: NDArray[np.bool_]
    settled: NDArray[np.bool_]
    provenance: Mapping[str, JsonValue] = field(default_factory=dict)

    @classmethod
    def load_run(cls, data: str | Path, name: str, backend: str) -> RunLogRecord:
        """The log of ``name`` on ``backend`` under ``data``, or a refusal naming the
        ``simulate`` stage and how to run it."""
        where = {"label": run_label(name, backend), "name": name, "backend": backend}
        file = RUN_LOG.require(data, **where)
        arrays, prov = RUN_LOG.read(file, where=where)
        return cls._build(arrays, prov)


@dataclass(frozen=True)
class ServoProgramRecord(_Record):
    """``deploy/<name>.npz``, the ``deploy`` stage's PCA9685 counts per servo frame.

    Attributes:
        t: (F,) frame times, s; q: (F, n) commanded angles, rad.
        counts: (F, C) off counts per channel; channels: the driven channels.
        frame_hz: frames per second; count_us: one count, us.
        provenance: the parsed provenance.
    """

    SPEC: ClassVar[ArtifactSpec] = SERVO_PROGRAM

    t: Float
    q: Float
    counts: NDArray[np.int64]
    channels: tuple[int, ...]
    frame_hz: float
    count_us: float
    provenance: Mapping[str, JsonValue] = field(default_factory=dict)

    @classmethod
    def _decode(cls, arrays: dict[str, NDArray[Any]]) -> dict[str, Any]:
        out: dict[str, Any] = dict(arrays)
        out["channels"] = tuple(int(c) for c in out["channels"])
        out["frame_hz"] = float(out["frame_hz"])
        out["count_us"] = float(out["count_us"])
        return out


@dataclass(frozen=True)
class StudySeriesRecord:
    """A study's time series (``studies/<study>/<name>/<case>.npz``, or the actuator
    study's ``studies/actuator/<name>.npz``): arrays under the study's own keys.

    Attributes:
        series: key -> array (any key but ``provenance``).
        provenance: the parsed provenance.
    """

    series: Mapping[str, NDArray[np.generic]]
    provenance: Mapping[str, JsonValue] = field(default_factory=dict)

    @staticmethod
    def path(data: str | Path, study: str, name: str, case: str | None = None) -> Path:
        """A case's file (``studies/<study>/<name>/<case>.npz``), or with ``case`` None the
        actuator study's ``studies/actuator/<name>.npz``."""
        if case is None:
            if study != "actuator":
                raise TattotronixError(f"study '{study}' stores one series per case: give "
                                       "the case")
            return ACTUATOR_SERIES.path(data, name=name)
        return STUDY_SERIES.path(data, study=study, name=name, case=case)

    def save(self, file: str | Path, provenance: str) -> None:
        """Write the series and ``provenance`` (:func:`make_provenance`) to ``file``."""
        STUDY_SERIES.write(file, self.series, provenance)

    @classmethod
    def load(cls, file: str | Path, study: str,
             keys: Sequence[str] = ()) -> StudySeriesRecord:
        """Read a study's series; ``keys`` are required (every key is read).

        Raises:
            TattotronixError: a key of ``keys`` or the provenance is missing, or the file is
                unreadable; the message names the study's stage.
        """
        arrays, prov = STUDY_SERIES.read(file, keys=(), where={"study": study})
        missing = [k for k in keys if k not in arrays]
        if missing:
            raise STUDY_SERIES.refuse(file, "missing key" + ("s " if len(missing) > 1
                                                             else " ")
                                      + ", ".join(repr(k) for k in missing),
                                      {"study": study})
        return cls(arrays, prov)
