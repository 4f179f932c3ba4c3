"""Typed schemas of every Hydra config group (dataclasses registered in the ConfigStore).

These dataclasses hold every key, its type, its range and its default: a default is written
here once. The YAML files under ``conf/`` hold only what is not a default (the robot's
description, the studies' cases, the board's calibration, a surface option's choice) and
whatever a project sets on purpose; a test refuses a ``conf/`` value equal to its default
here. Every group file names its schema first in its defaults list, so a typo or a bad
value stops composition with a message that names the key (and, for enums, the allowed
values). :func:`register` is called from the Hydra plugin in ``hydra_plugins/`` so that any
Hydra process (a stage, a test, or DVC's own composition in ``dvc exp run``) sees them.

The same classes are the typed settings the library takes. The stage runner
(:mod:`tattotronix.stage`) turns the composed config into a :class:`Config` once
(:func:`tattotronix.config.params.to_settings`); library functions take the section they
need (``IkConfig``, ``RobotConfig``, ...), never a ``DictConfig``. Every class is declared
with :func:`settings`: a dataclass that is frozen once built (assigning a field raises
``FrozenInstanceError``), and that type checkers treat as ``@dataclass(frozen=True)``. It
is not a frozen dataclass to OmegaConf, which makes such a node read-only and then cannot
compose the YAML into it. Defaults live here only: library code reads them from these
classes, never copies them.

Units: SI inside (m, kg, rad, s); millimetres only where the name says ``_mm``. A section
converts its ``_mm`` keys once, in properties named in SI (``CollisionConfig.margin_m``,
``ToolpathConfig.clearance_m``, ...); the library uses those.

Ranges: every numeric key declares its allowed values once, next to its default
(:func:`bounded`: a :class:`Range` in the field's metadata; for a list, each item).
:func:`out_of_range` checks a whole settings object against them, and
:func:`tattotronix.config.params.to_settings` refuses a config that breaks one, naming the
full key, the value and the range, before any stage does work. The bounds admit every value
in ``conf/`` and the study sweeps; the lowest spacings (``toolpath.pitch_mm``,
``toolpath.step_mm``, ``mask.res_mm``, ...) are the smallest the pipeline was measured to
still run on the built-in emblem (README, "Configuration").
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from collections.abc import Callable
from dataclasses import FrozenInstanceError, dataclass, field
from enum import Enum
from typing import Any, TypeAlias, TypeVar, dataclass_transform, overload

from omegaconf import MISSING

from tattotronix.io.outputs import PIPELINE_DATA

__all__ = [
    "ActuatorOption",
    "ActuatorStudyConfig",
    "ArtworkConfig",
    "Backend",
    "BenchConfig",
    "BoxInertial",
    "build_exact",
    "CollisionConfig",
    "Config",
    "ControlCase",
    "ControlStudyConfig",
    "ControllerConfig",
    "DrawConfig",
    "FillStyle",
    "FrameConfig",
    "HardwareConfig",
    "IkConfig",
    "InertialConfig",
    "JointConfig",
    "KinematicsStudyConfig",
    "MaskConfig",
    "MaskMethod",
    "NotExact",
    "MassModel",
    "PanelConfig",
    "PathsConfig",
    "PenConfig",
    "PhantomConfig",
    "Plain",
    "PlantConfig",
    "RANGE_KEY",
    "Range",
    "RobotConfig",
    "RobustnessStudyConfig",
    "ServoConfig",
    "ServoMountConfig",
    "ServoSpreadConfig",
    "Structure",
    "StudyConfig",
    "SurfaceConfig",
    "SurfaceKind",
    "Tool",
    "ToolpathConfig",
    "TrajectoryConfig",
    "bounded",
    "out_of_range",
    "range_of",
    "register",
    "settings",
    "to_dict",
]

_T = TypeVar("_T")
#: the plain value of a setting: what ``to_dict`` and ``params.yaml`` hold
Plain: TypeAlias = None | bool | int | float | str | list["Plain"] | dict[str, "Plain"]


def _frozen_setattr(self: object, name: str, value: object) -> None:
    if self.__dict__.get("_built"):
        raise FrozenInstanceError(f"cannot assign to field {name!r}: settings are frozen")
    object.__setattr__(self, name, value)


def _frozen_delattr(self: object, name: str) -> None:
    raise FrozenInstanceError(f"cannot delete field {name!r}: settings are frozen")


def _built(self: object) -> None:
    object.__setattr__(self, "_built", True)


@dataclass_transform(frozen_default=True, field_specifiers=(field,))
def settings(cls: type[_T]) -> type[_T]:
    """Declare a schema class: a dataclass whose instances are frozen once built.

    OmegaConf builds and merges the class's fields (it is not a frozen dataclass to
    OmegaConf); an instance refuses any assignment after ``__init__`` (at run time) and is
    ``@dataclass(frozen=True)`` to type checkers (``dataclass_transform``).
    """
    if "__post_init__" in cls.__dict__:
        raise TypeError(f"{cls.__name__}: a settings class has no __post_init__ of its own")
    hooks: dict[str, Callable[..., None]] = {
        "__setattr__": _frozen_setattr, "__delattr__": _frozen_delattr,
        "__post_init__": _built}
    for name, hook in hooks.items():
        setattr(cls, name, hook)
    return dataclass(unsafe_hash=True)(cls)


def to_dict(obj: object) -> dict[str, Plain]:
    """The plain dict of a settings object: what ``OmegaConf.to_container(cfg,
    resolve=True, enum_to_str=True)`` gives for the same config (field order, enum names),
    so provenance written from either is the same."""
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        raise TypeError(f"to_dict takes a settings object, not {type(obj).__name__}")
    plain = _plain(obj)
    assert isinstance(plain, dict)
    return plain


def _plain(value: object) -> Plain:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Enum):
        return value.name
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    assert value is None or isinstance(value, bool | int | float | str), value
    return value


class NotExact(ValueError):
    """:func:`build_exact` does not take this value as it stands (OmegaConf may still
    convert it, or refuse it with its own message)."""


def build_exact(cls: type[_T], plain: object, key: str = "") -> _T:
    """The settings object of ``cls`` from plain containers whose every value already has
    its field's type (what :func:`to_dict` gives, ``params.yaml`` holds, or a YAML scalar
    parses to): the object OmegaConf's merge into the schema and ``to_object`` would build,
    in milliseconds instead of the second theirs take.

    Exact means: a ``float`` field takes an int or a float (as a float), every other field
    only its own type; an enum its member's name; a missing key the field's default. A
    value it does not take this way (a string for a number, an unknown key, a missing
    mandatory value, an interpolation) raises :class:`NotExact`, and the caller goes the
    OmegaConf way, which converts it or refuses it with its message. Ranges are not
    checked here (:func:`out_of_range`).
    """
    if not isinstance(plain, dict):
        raise NotExact(f"{key or cls.__name__}: a mapping, not {type(plain).__name__}")
    hints = _hints(typing.cast(Any, cls))
    unknown = set(plain) - set(hints)
    if unknown:
        raise NotExact(f"{key}: unknown keys {sorted(map(str, unknown))}")
    kwargs: dict[str, object] = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        name = f"{key}.{f.name}" if key else f.name
        if f.name in plain:
            kwargs[f.name] = _exact(hints[f.name], plain[f.name], name)
        elif f.default_factory is not dataclasses.MISSING:
            kwargs[f.name] = f.default_factory()
        elif f.default is dataclasses.MISSING or f.default == MISSING:
            raise NotExact(f"{name}: missing")
        else:
            kwargs[f.name] = f.default
    return cls(**kwargs)


@functools.cache
def _hints(cls: Any) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _exact(hint: Any, value: object, key: str) -> object:
    origin = typing.get_origin(hint)
    if hint is Any:
        if isinstance(value, str) and "${" in value:
            raise NotExact(f"{key}: an interpolation")
        return _plain_copy(value, key)
    if origin in (types.UnionType, typing.Union):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None:
            return None
        if len(args) != 1:
            raise NotExact(f"{key}: a union")
        return _exact(args[0], value, key)
    if origin is list:
        (item,) = typing.get_args(hint)
        if not isinstance(value, list):
            raise NotExact(f"{key}: a list, not {type(value).__name__}")
        return [_exact(item, v, f"{key}[{i}]") for i, v in enumerate(value)]
    if origin is dict:
        k_type, item = typing.get_args(hint)
        if not isinstance(value, dict) or k_type is not str:
            raise NotExact(f"{key}: a mapping, not {type(value).__name__}")
        return {k: _exact(item, v, f"{key}.{k}") for k, v in value.items()
                if isinstance(k, str) or _raise(f"{key}: a key {k!r}")}
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        return build_exact(hint, value, key)
    if isinstance(hint, type) and issubclass(hint, Enum):
        if isinstance(value, str) and value in hint.__members__:
            return hint[value]
        raise NotExact(f"{key}: not a name of {hint.__name__}")
    if isinstance(value, str) and "${" in value:
        raise NotExact(f"{key}: an interpolation")
    if hint is float and isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    if hint in (bool, int, str) and type(value) is hint:
        return value
    raise NotExact(f"{key}: {type(value).__name__} for {getattr(hint, '__name__', hint)}")


def _raise(message: str) -> bool:
    raise NotExact(message)


def _plain_copy(value: object, key: str) -> object:
    if isinstance(value, dict):
        return {str(k): _plain_copy(v, key) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain_copy(v, key) for v in value]
    if value is None or isinstance(value, bool | int | float | str):
        return value
    raise NotExact(f"{key}: {type(value).__name__}")


#: a joint angle's bound, rad (a full turn either way)
TURN = math.tau
#: the bound of a position in the arm frame, m (the arm reaches 0.3 m)
REACH_M = 10.0

#: the smallest spacings the pipeline was measured to still run at on the built-in emblem
#: (README, "Configuration": time and memory at each)
MIN_RES_MM = 0.04
MIN_PITCH_MM = 0.05
MIN_STEP_MM = 0.005
MIN_MAX_STEP_MM = 0.01
MIN_COLLISION_RES_MM = 1e-6
MIN_INK_RES_MM = 0.01
MIN_DT_S = 1e-5

#: the metadata key of a field's :class:`Range`
RANGE_KEY = "range"


@dataclass(frozen=True)
class Range:
    """The values a numeric setting allows (each item, for a list setting).

    Attributes:
        lo, hi: the bounds (always finite: nan and inf are never allowed).
        lo_open, hi_open: the bound itself is excluded.
        unit: the unit, for messages (``"mm"``, ``"rad/s"``).
        why: what the key is or why the bound, for messages.
    """

    lo: float
    hi: float
    lo_open: bool = False
    hi_open: bool = False
    unit: str = ""
    why: str = ""

    def admits(self, value: float) -> bool:
        """Whether ``value`` lies in the range (nan never does; ints compare exactly)."""
        if isinstance(value, float) and math.isnan(value):
            return False
        above = value > self.lo if self.lo_open else value >= self.lo
        below = value < self.hi if self.hi_open else value <= self.hi
        return bool(above and below)

    def describe(self, integer: bool = False) -> str:
        """``">= 0.05 and <= 100 mm"`` (``"an integer >= 1 and <= 1000"``)."""
        def num(x: float) -> str:
            return str(int(x)) if integer and x.is_integer() else f"{x:g}"

        text = (f"{'>' if self.lo_open else '>='} {num(self.lo)} and "
                f"{'<' if self.hi_open else '<='} {num(self.hi)}")
        return ("an integer " if integer else "") + text + (f" {self.unit}" if self.unit else "")

    def problems(self, key: str, value: object) -> list[str]:
        """What is wrong with ``value`` at ``key`` (a list: each item, ``key[i]``)."""
        if value is None or isinstance(value, bool):
            return []
        if isinstance(value, list | tuple):
            return [p for i, v in enumerate(value) for p in self.problems(f"{key}[{i}]", v)]
        if not isinstance(value, int | float) or self.admits(value):
            return []
        shown = f"{value:g}" if isinstance(value, float) else str(value)
        why = f": {self.why}" if self.why else ""
        return [f"{key} must be {self.describe(isinstance(value, int))} (got {shown}){why}"]


@overload
def bounded(default: _T, *, lo: float, hi: float, lo_open: bool = ...,
            hi_open: bool = ..., unit: str = ..., why: str = ...) -> _T: ...


@overload
def bounded(*, factory: Callable[[], _T], lo: float, hi: float, lo_open: bool = ...,
            hi_open: bool = ..., unit: str = ..., why: str = ...) -> _T: ...


def bounded(default: object = dataclasses.MISSING, *,
            factory: Callable[[], object] | None = None, lo: float, hi: float,
            lo_open: bool = False, hi_open: bool = False, unit: str = "",
            why: str = "") -> object:
    """A numeric field with its allowed :class:`Range` (each item, for a list field).

    ``default`` (or ``factory`` for a list) is the field's default, as in
    :func:`dataclasses.field`.
    """
    meta = {RANGE_KEY: Range(float(lo), float(hi), lo_open, hi_open, unit, why)}
    if factory is not None:
        return field(default_factory=factory, metadata=meta)
    return field(default=default, metadata=meta)


def range_of(f: dataclasses.Field[object]) -> Range | None:
    """The :class:`Range` a field was declared with (:func:`bounded`), or None."""
    rng = f.metadata.get(RANGE_KEY)
    return rng if isinstance(rng, Range) else None


def out_of_range(obj: object, prefix: str = "") -> list[str]:
    """Every numeric setting of the settings object ``obj`` outside its :class:`Range`,
    each as ``"<full key> must be <range> (got <value>)..."``; nested sections, lists and
    maps of sections are walked (``robot.joints[0].effort``, ``robot.printed.base_link.mass``).
    """
    found: list[str] = []
    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        key, value = f"{prefix}{f.name}", getattr(obj, f.name)
        rng = range_of(f)
        if rng is not None:
            found += rng.problems(key, value)
        else:
            found += _nested_out_of_range(key, value)
    return found


def _nested_out_of_range(key: str, value: object) -> list[str]:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return out_of_range(value, f"{key}.")
    if isinstance(value, list | tuple):
        return [p for i, v in enumerate(value) for p in _nested_out_of_range(f"{key}[{i}]", v)]
    if isinstance(value, dict):
        return [p for k, v in value.items() for p in _nested_out_of_range(f"{key}.{k}", v)]
    return []


class MassModel(Enum):
    """Which inertial table the robot description uses."""

    printed = "printed"
    box = "box"


class Tool(Enum):
    """What is mounted on ``tool0``."""

    tattoo = "tattoo"
    none = "none"


class MaskMethod(Enum):
    """How an artwork becomes an ink mask."""

    threshold = "threshold"
    edges = "edges"


class Anchor(Enum):
    """The point of a drawing that ``mask.at_mm`` places on the panel: its grid's centre,
    or a corner or the middle of a side of its extent (before ``mask.rotate_deg``)."""

    centre = "centre"
    top_left = "top_left"
    top = "top"
    top_right = "top_right"
    left = "left"
    right = "right"
    bottom_left = "bottom_left"
    bottom = "bottom"
    bottom_right = "bottom_right"


class FillStyle(Enum):
    """How regions are filled: one hatch, a cross-hatch (a second at 90 degrees), rings
    parallel to the outline (concentric), or a hatch at the needle's width (solid)."""

    hatch = "hatch"
    cross = "cross"
    concentric = "concentric"
    solid = "solid"


@settings
class JointConfig:
    """One revolute joint: fixed origin (parent frame, m / rad), then a rotation about ``axis``."""

    name: str = MISSING
    parent: str = MISSING
    child: str = MISSING
    xyz: list[float] = bounded(MISSING, lo=-REACH_M, hi=REACH_M, unit="m")
    rpy: list[float] = bounded(factory=lambda: [0.0, 0.0, 0.0], lo=-TURN, hi=TURN,
                               unit="rad")
    axis: list[float] = bounded(MISSING, lo=-1, hi=1, why="a direction, e.g. [0, 0, 1]")
    lower: float = bounded(MISSING, lo=-TURN, hi=TURN, unit="rad")
    upper: float = bounded(MISSING, lo=-TURN, hi=TURN, unit="rad")
    effort: float = bounded(20.0, lo=0, lo_open=True, hi=1e4, unit="N m")
    velocity: float = bounded(1.5, lo=0, lo_open=True, hi=1e3, unit="rad/s")


@settings
class FrameConfig:
    """A frame rigidly attached to ``parent`` (no body of its own)."""

    name: str = MISSING
    parent: str = MISSING
    xyz: list[float] = bounded(MISSING, lo=-REACH_M, hi=REACH_M, unit="m")
    rpy: list[float] = bounded(factory=lambda: [0.0, 0.0, 0.0], lo=-TURN, hi=TURN,
                               unit="rad")


@settings
class InertialConfig:
    """Mass (kg), CoM in the link frame (m) and inertia about the CoM in link axes (kg m^2).

    ``inertia`` is ``[ixx, ixy, ixz, iyy, iyz, izz]``.
    """

    mass: float = bounded(MISSING, lo=0, lo_open=True, hi=1e3, unit="kg")
    com: list[float] = bounded(MISSING, lo=-REACH_M, hi=REACH_M, unit="m")
    inertia: list[float] = bounded(MISSING, lo=-1e3, hi=1e3, unit="kg m^2")


@settings
class BoxInertial:
    """The ``box`` mass model for one link: a solid box of the link's bounding box.

    Its ``centre`` and ``size`` (m) also size the primitive geometry used without meshes.
    """

    mass: float = bounded(MISSING, lo=0, lo_open=True, hi=1e3, unit="kg")
    centre: list[float] = bounded(MISSING, lo=-REACH_M, hi=REACH_M, unit="m")
    size: list[float] = bounded(MISSING, lo=0, lo_open=True, hi=REACH_M, unit="m")


@settings
class PenConfig:
    """The placeholder tattoo pen on ``tool0``: a cylinder along tool0 +z (m, kg)."""

    length: float = bounded(MISSING, lo=0, lo_open=True, hi=1, unit="m")
    radius: float = bounded(MISSING, lo=0, lo_open=True, hi=0.1, unit="m")
    mass: float = bounded(MISSING, lo=0, lo_open=True, hi=10, unit="kg")
    # visual barrel; the rest is the tip cone
    barrel_length: float = bounded(MISSING, lo=0, lo_open=True, hi=1, unit="m")


@settings
class PanelConfig:
    """The work panel in the arm frame (m). Visual only: the needle may enter it."""

    centre: list[float] = bounded(factory=lambda: [0.21, 0.0, 0.0025], lo=-REACH_M,
                                  hi=REACH_M, unit="m")
    size: list[float] = bounded(factory=lambda: [0.20, 0.14, 0.005], lo=0, lo_open=True,
                                hi=REACH_M, unit="m")

    @property
    def size_mm(self) -> tuple[float, float]:
        """Width and height of the panel, mm."""
        return float(self.size[0]) * 1e3, float(self.size[1]) * 1e3


@settings
class BenchConfig:
    """The bench under the arm (m); its top is the arm frame's z = 0."""

    size: list[float] = bounded(factory=lambda: [0.70, 0.50, 0.75], lo=0, lo_open=True,
                                hi=REACH_M, unit="m")


class ServoCommand(Enum):
    """How a catalogue servo is commanded: a PWM pulse (through the PCA9685) or a serial bus
    with an encoder (a position in encoder steps)."""

    pwm = "pwm"
    bus = "bus"


@settings
class ServoConfig:
    """A catalogue servo: its mass and body (the mass model) and how it behaves (the servo
    plant; docs/servos.md gives each figure's source).

    The servo's own loop (docs/servos.md, "The servo model"): the drive saturates at
    ``stall_nm`` once the error exceeds ``band_deg``, and back-EMF limits the no-load speed
    to ``speed_rad_s``; it rests anywhere within half its dead band of the command; the
    gears have ``backlash_deg`` of play; its pulse-to-angle map bends by up to
    ``nonlinearity_deg`` off the straight line; it acts ``latency_ms`` after a pulse.
    A ``bus`` servo takes positions in steps of ``step_deg`` and holds within one step.
    """

    mass: float = bounded(MISSING, lo=0, lo_open=True, hi=10, unit="kg")
    size: list[float] = bounded(MISSING, lo=0, lo_open=True, hi=1, unit="m")
    deadband_us: float = bounded(MISSING, lo=0, hi=1000, unit="us")
    command: ServoCommand = ServoCommand.pwm
    stall_nm: float = bounded(MISSING, lo=0, lo_open=True, hi=100, unit="N m")
    speed_rad_s: float = bounded(MISSING, lo=0, lo_open=True, hi=1000, unit="rad/s")
    band_deg: float = bounded(MISSING, lo=0, lo_open=True, hi=90, unit="deg")
    backlash_deg: float = bounded(MISSING, lo=0, hi=45, unit="deg")
    nonlinearity_deg: float = bounded(MISSING, lo=0, hi=45, unit="deg")
    armature_kgm2: float = bounded(MISSING, lo=0, hi=1, unit="kg m^2")
    latency_ms: float = bounded(MISSING, lo=0, hi=1000, unit="ms")
    step_deg: float = bounded(0.0, lo=0, hi=10, unit="deg")  # bus servos: one encoder step


@settings
class ServoMountConfig:
    """Where a servo sits: on ``link``, centred on joint ``at`` (or ``tool`` axis)."""

    link: str = MISSING
    servo: str = MISSING
    at: str = MISSING  # a joint name, or "tool" for the tool servo on the tool axis
    count: int = bounded(1, lo=1, hi=16, why="servos at this mount")


@settings
class RobotConfig:
    """The one robot description: URDF, MJCF and every loader are generated from it. The
    description itself (names, joints, frames, pen, masses, servos) is data, in
    ``conf/robot/<name>.yaml``; the settings around it have their defaults here."""

    name: str = MISSING
    base_link: str = MISSING
    joints: list[JointConfig] = MISSING
    tool0: FrameConfig = MISSING
    tcp: FrameConfig = MISSING
    tool: Tool = Tool.tattoo
    pen: PenConfig = MISSING
    mass_model: MassModel = MassModel.printed
    printed: dict[str, InertialConfig] = MISSING
    box: dict[str, BoxInertial] = MISSING
    cad_dir: str | None = None
    mesh_scale: float = bounded(0.01, lo=0, lo_open=True, hi=1e3,
                                why="mesh units to m; the CAD meshes are in cm")
    gravity: float = bounded(9.80665, lo=0, hi=100, unit="m/s^2")
    bench: BenchConfig = field(default_factory=BenchConfig)
    panel: PanelConfig = field(default_factory=PanelConfig)
    # mass integration (the ``mass`` stage)
    pla_density: float = bounded(1240.0, lo=0, lo_open=True, hi=1e5,
                                 unit="kg/m^3")  # solid PLA
    # share of solid: 20 % infill, perimeters dominate
    printed_fraction: float = bounded(0.35, lo=0, lo_open=True, hi=1)
    servos: dict[str, ServoConfig] = MISSING
    servo_mounts: list[ServoMountConfig] = MISSING


@settings
class ArtworkConfig:
    """Which artwork to draw. ``source`` null means the built-in emblem."""

    source: str | None = None  # a PNG, JPG or SVG path; null: the built-in emblem
    name: str | None = None  # defaults to the file's stem ("emblem" for the built-in)
    # refuse larger images (decompression bombs) and grids
    max_pixels: int = bounded(40_000_000, lo=1, hi=1_000_000_000, unit="px")
    # an SVG may refer to files in its own folder (<image href="photo.png">); false: an SVG
    # must be self-contained (any reference to another file or a URL is refused)
    svg_local_files: bool = False
    # an SVG's stroked lines are drawn from its geometry, not from the mask (line art)
    vector: bool = False


@settings
class MaskConfig:
    """Artwork to ink mask."""

    # the drawing's width; null: an SVG's own physical width (mm, cm, in, pt, pc),
    # else default_width_mm (tattotronix/art/sizing.py)
    width_mm: float | None = bounded(None, lo=0, lo_open=True, hi=1000, unit="mm")
    default_width_mm: float = bounded(150.0, lo=0, lo_open=True, hi=1000, unit="mm",
                                      why="the width of an artwork with no size of its own")
    # the drawing's height instead of its width (its width follows from its aspect)
    height_mm: float | None = bounded(None, lo=0, lo_open=True, hi=1000, unit="mm")
    # where the drawing lies on the panel (tattotronix/art/place.py): its anchor point
    # lands at at_mm (from the panel's centre: u along the arm's x, v along its y), and
    # it turns rotate_deg anticlockwise about it; checked against the panel
    anchor: Anchor = Anchor.centre
    at_mm: list[float] = bounded(factory=lambda: [0.0, 0.0], lo=-1000, hi=1000, unit="mm")
    rotate_deg: float = bounded(0.0, lo=-360, hi=360, unit="deg")
    res_mm: float = bounded(0.25, lo=MIN_RES_MM, hi=10, unit="mm",
                            why="the mask grid's coarsest pixel")
    # an SVG's thinnest stroke spans at least this many mask pixels: res_mm is refined
    # until it does (a 0.5 mm line at 0.25 mm/px is thresholded into dashes); 0: never
    min_line_px: float = bounded(3.0, lo=0, hi=100, unit="px")
    method: MaskMethod = MaskMethod.threshold
    min_region_mm2: float = bounded(4.0, lo=0, hi=1e5, unit="mm^2")
    edge_sigma_px: float = bounded(2.0, lo=0, hi=100, unit="px")
    edge_k: float = bounded(1.0, lo=0, hi=100, why="edges: ink above mean + edge_k * std")
    # threshold: when the dark side covers more than half the canvas, draw the light side
    auto_invert: bool = True


@settings
class ToolpathConfig:
    """Mask to ordered needle path (mm in the panel plane)."""

    pitch_mm: float = bounded(1.2, lo=MIN_PITCH_MM, hi=100, unit="mm",
                              why="the hatch spacing")
    # the needle's ink line width: outlines run half of it inside the artwork's edge
    needle_width_mm: float = bounded(0.3, lo=0, lo_open=True, hi=10, unit="mm")
    compensate: bool = True  # true: compensate the needle width; narrow parts as line art
    # parts narrower than this are drawn as one pass along their centreline (0: none)
    line_max_mm: float = bounded(0.6, lo=0, hi=100, unit="mm")
    # the raster the planned ink is measured on against the artwork (finer than the
    # simulated ink's draw.ink_res_mm: the plan has no tracking error to blur it)
    ink_res_mm: float = bounded(0.025, lo=MIN_INK_RES_MM, hi=10, unit="mm",
                                why="the planned ink raster's pixel")
    fill_style: FillStyle = FillStyle.hatch
    fill_angle_deg: float = bounded(0.0, lo=-180, hi=180, unit="deg",
                                    why="the hatch's angle from the x axis")
    step_mm: float = bounded(0.15, lo=MIN_STEP_MM, hi=100, unit="mm",
                             why="the point spacing along a stroke")
    clearance_mm: float = bounded(8.0, lo=0, hi=100, unit="mm")
    plunge_mm: float = bounded(1.5, lo=0, hi=20, unit="mm")
    # the slow last stretch of each plunge (chosen by the approach study, stages/approach.py:
    # as good at the needle entry as a longer one, for less cycle time)
    approach_mm: float = bounded(2.0, lo=0, hi=120, unit="mm")
    min_loop_px: int = bounded(8, lo=1, hi=1_000_000, unit="px")
    feed_mark_mm_s: float = bounded(6.0, lo=0.01, hi=1000, unit="mm/s")
    feed_travel_mm_s: float = bounded(60.0, lo=0.1, hi=10_000, unit="mm/s")
    # extra fixed cost per needle entry in the ordering objective
    lift_s: float = bounded(0.0, lo=0, hi=3600, unit="s")
    outlines_first: bool = True
    panel_origin: list[float] = bounded(factory=lambda: [0.21, 0.0, 0.005], lo=-1, hi=1,
                                        unit="m")

    @property
    def needle_um(self) -> float:
        """The ink line width, um."""
        return float(self.needle_width_mm) * 1e3

    @property
    def pitch_m(self) -> float:
        """The hatch spacing, m."""
        return float(self.pitch_mm) / 1000

    @property
    def clearance_m(self) -> float:
        """The needle's travel height above the panel surface, m."""
        return float(self.clearance_mm) / 1000

    @property
    def plunge_m(self) -> float:
        """The marking depth below the surface, m."""
        return float(self.plunge_mm) / 1000

    @property
    def feed_mark_m_s(self) -> float:
        """The marking (and approach) feed, m/s."""
        return float(self.feed_mark_mm_s) / 1000

    @property
    def feed_travel_m_s(self) -> float:
        """The original's travel feed, m/s."""
        return float(self.feed_travel_mm_s) / 1000


@settings
class IkConfig:
    """Whole-path IK: damped least squares on the 5x5 task Jacobian (docs/kinematics.md,
    "Inverse kinematics"; the original's: docs/original.md, "3 Inverse kinematics")."""

    # the damped-least-squares lambda, added to J J^T as is
    dls_lambda: float = bounded(1e-3, lo=0, lo_open=True, hi=1,
                                why="the damped-least-squares lambda")
    max_iter: int = bounded(200, lo=1, hi=100_000, why="iterations per IK solve")
    tol: float = bounded(1e-6, lo=1e-12, hi=1e-3,
                         why="the IK's convergence bound on |e| (m, unitless)")
    seed: list[float] = bounded(factory=lambda: [0.0, 0.6, -0.9, 0.0, -1.2], lo=-TURN,
                                hi=TURN, unit="rad")
    needle_axis: list[float] = bounded(factory=lambda: [0.0, 0.0, -1.0], lo=-1, hi=1,
                                       why="a direction, e.g. [0, 0, -1]")
    # batched solver: an anchor every 5 mm of path
    anchor_spacing_m: float = bounded(0.005, lo=1e-6, hi=1, unit="m")
    verify_pos_tol_m: float = bounded(2e-6, lo=1e-12, hi=1e-2, unit="m")
    verify_axis_tol_rad: float = bounded(2e-6, lo=1e-12, hi=0.1, unit="rad")


@settings
class TrajectoryConfig:
    """Time law along the IK path: feeds, joint limits, ramps.

    Marking and approach run at ``toolpath.feed_mark_mm_s``; joint velocity limits come
    from the robot's joint table. ``speed`` (root key) rescales the whole motion.
    """

    # cap on the tip speed of travel moves
    travel_feed_mm_s: float = bounded(200.0, lo=0.1, hi=10_000, unit="mm/s")
    # per-joint acceleration limit. The original's MoveIt limit was 7.5 (1.5 rad/s reached in
    # 0.2 s, an arbitrary ramp); 10 costs at most J_eff * a = 0.04 N m of torque (0.2 % of
    # the 20 N m effort, 4 % of an MG996R) and brings the cycle within 10 % of marking-only
    # time
    accel_rad_s2: float = bounded(10.0, lo=0.01, hi=10_000, unit="rad/s^2")
    # every joint's jerk limit, chosen from the time-law study (null: acceleration-limited;
    # see docs/timelaw.md)
    jerk_rad_s3: float | None = bounded(500.0, lo=0, lo_open=True, hi=1e6, unit="rad/s^3")
    # the tip's acceleration limit while marking (tangential and centripetal together)
    tip_accel_mm_s2: float | None = bounded(100.0, lo=0, lo_open=True, hi=1e6,
                                            unit="mm/s^2")
    # a blended travel move's first tangent reach (raised through lifts_mm if it fails)
    blend_reach_mm: float = bounded(4.0, lo=0, hi=100, unit="mm")
    # longer segments (travel, lifts) get points on the tip line
    max_step_mm: float = bounded(0.5, lo=MIN_MAX_STEP_MM, hi=100, unit="mm",
                                 why="the longest chord kept as is")
    # travel between strokes, from home to the first stroke and the way home. planned: one
    # blended joint-space move from the ink up the needle, over at the clearance height and
    # down the needle (checked for collision and clearance); straight: the original's
    # straight tip lines at clearance
    travel: str = "planned"
    home: list[float] = bounded(factory=lambda: [0.0, 0.0, 0.0, 0.0, 0.0], lo=-TURN,
                                hi=TURN, unit="rad")
    from_home: bool = True  # planned travel: start at home and return home
    lifts_mm: list[float] = bounded(factory=lambda: [10.0, 20.0, 40.0, 80.0], lo=0,
                                    hi=500, unit="mm")

    @property
    def travel_feed_m_s(self) -> float:
        """The cap on the tip speed of travel moves, m/s."""
        return float(self.travel_feed_mm_s) / 1000

    @property
    def tip_accel_m_s2(self) -> float | None:
        """The tip's acceleration limit while marking, m/s^2 (``None``: none)."""
        return None if self.tip_accel_mm_s2 is None else float(self.tip_accel_mm_s2) / 1000

    @property
    def blend_reach_m(self) -> float:
        """A blended travel move's first tangent reach, m."""
        return float(self.blend_reach_mm) / 1000

    @property
    def max_step_m(self) -> float:
        """The longest chord kept as is (longer ones get points on the tip line), m."""
        return float(self.max_step_mm) / 1000

    @property
    def lifts_m(self) -> list[float]:
        """The lift heights planned travel tries, m."""
        return [float(h) / 1000 for h in self.lifts_mm]


@settings
class CollisionConfig:
    """Collision checking (``stages/collision.py``) and the planned travel's margin."""

    # least clearance every trajectory sample, the motion between samples and every planned
    # travel move must keep
    margin_mm: float = bounded(1.0, lo=0, hi=100, unit="mm")
    # bisect the motion between samples down to this bound
    resolution_mm: float = bounded(0.1, lo=MIN_COLLISION_RES_MM, hi=100, unit="mm",
                                   why="the bisection bound between samples")

    @property
    def margin_m(self) -> float:
        """The least clearance to keep, m."""
        return float(self.margin_mm) / 1000

    @property
    def resolution_m(self) -> float:
        """The bisection bound of the motion between samples, m."""
        return float(self.resolution_mm) / 1000


class Structure(Enum):
    """Controller structure (docs/control.md, "The controller"; docs/original.md, "5.2
    Controller structure").

    ``pid``: no feedforward; ``pid_g``: + gravity G(q) at the measured q; ``pid_g_v``: +
    velocity feedforward (the derivative acts on the error, qd_r - qd);
    ``computed_torque``: + M(q) qdd_r + C(q, qd) qd as well.
    """

    pid = "pid"
    pid_g = "pid_g"
    pid_g_v = "pid_g_v"
    computed_torque = "computed_torque"


class Backend(Enum):
    """Which plant ``draw.py`` runs on (``arm``: the real arm, or its dry run)."""

    mujoco = "mujoco"
    pybullet = "pybullet"
    model = "model"
    servo = "servo"
    arm = "arm"


@settings
class ControllerConfig:
    """The joint controller shared by every plant (docs/control.md, "The controller";
    docs/original.md, "5.2 Controller structure" and "5.3 Tuning by pole placement").

    PID by pole placement on the effective inertia J_eff at ``tune_q`` (all three poles
    at -wn): Kp = 3 J wn^2, Kd = 3 J wn, Ki = J wn^3. The defaults are the original's
    recommended configuration.
    """

    structure: Structure = Structure.pid_g_v
    # one for every joint; wn T = 0.16 at 1 kHz, inside the sampled boundary 0.30-0.35
    wn: float = bounded(160.0, lo=0.1, hi=10_000, unit="rad/s")
    # the loop runs at this rate, zero-order hold between ticks (the original's
    # ros2_control update_rate)
    rate_hz: float = bounded(1000.0, lo=1, hi=10_000, unit="Hz")
    # null: each joint's effort limit (20 N m)
    torque_limit_nm: float | None = bounded(None, lo=0, lo_open=True, hi=1e4, unit="N m")
    # rad; null: the reference pose mid-way through the run
    tune_q: list[float] | None = bounded(None, lo=-TURN, hi=TURN, unit="rad")


@settings
class PlantConfig:
    """The simulated arm, whichever backend runs it."""

    # integration step (semi-implicit Euler in every backend; 1 kHz as the original)
    dt_s: float = bounded(0.001, lo=MIN_DT_S, hi=0.1, unit="s")
    # viscous joint friction, N m s/rad (none unless configured)
    damping: float = bounded(0.0, lo=0, hi=1000, unit="N m s/rad")
    # enforce the joint range (the model plant clamps); a correct drawing never reaches it
    joint_limits: bool = False
    # arm-bench contact (MuJoCo, PyBullet); the panel never resists, and the collision stage
    # checks the plan instead
    contacts: bool = False
    # a joint this far from its reference: the run diverged
    abort_error_rad: float = bounded(1.0, lo=0, lo_open=True, hi=TURN, unit="rad")


@settings
class ServoPlantConfig:
    """The servo plant (``backend=servo``; docs/servos.md): the arm on hobby servos playing
    the servo program. The servos' figures are ``robot.servos`` (their sources in
    docs/servos.md); these switch each imperfection and set the simulated calibration. Each
    imperfection can be switched off; with all off and ``quantise=false`` it is an ideal
    position servo following the program's angles."""

    # the servo type on every joint (a robot.servos name); null: as mounted (servo_mounts)
    type: str | None = None
    quantise: bool = True  # the PCA9685's counts (a bus servo's steps); false: exact angles
    deadband: bool = True  # the servo rests anywhere within half its dead band
    backlash: bool = True  # the gears' play between the servo and the link
    nonlinearity: bool = True  # the servo's pulse-to-angle map bends off the straight line
    lag: bool = True  # frame hold, latency, stall torque and speed limit (false: stiff, exact)
    # the simulated calibration (servo_pulse's procedure): widths measured per servo
    fit_points: int = bounded(9, lo=2, hi=200)
    fit_order: int = bounded(5, lo=1, hi=7)  # hardware.servos.DEFAULT_FIT_ORDER's
    protractor_deg: float = bounded(0.5, lo=0, hi=10, unit="deg")  # reading resolution
    # the stiff loop of lag=false, rad/s
    ideal_wn: float = bounded(300.0, lo=1, lo_open=False, hi=10_000, unit="rad/s")


@settings
class CompensateConfig:
    """What the servo program corrects for (``deploy``, the real arm and the servo plant;
    docs/servos.md, "Calibration that fixes what it can"). The amounts are the mounted
    servos' catalogue figures (``robot.servos``) and, for the sag, the mass model; the
    pulse-map fit comes from the calibration's measured points (``stages/servo_pulse.py
    record=...``)."""

    fit: bool = False  # the servo plant: measure each servo first, deploy through the fit
    backlash: bool = False  # every joint arrives moving one way; reversals pre-load the play
    deadband: bool = False  # counts pushed past the dead band, so each move lands
    # the pose plus the torque it needs (gravity and motion) over the servo's gain, so the
    # proportional band does not leave it short (on: the servo study shows what it buys)
    sag: bool = True
    # every command sent ahead by the servo's latency, half a frame and its own lag
    lead: bool = True


@settings
class DrawConfig:
    """Error bookkeeping and the ink image of a simulated drawing (docs/original.md, "5.5
    Tracking error"; docs/control.md, "Ink against the plan")."""

    sample_s: float = bounded(0.02, lo=1e-5, hi=60, unit="s")  # tracking error sampling
    # "settled" excludes settle_periods / wn after each entry
    settle_periods: float = bounded(4.0, lo=0, hi=1000)
    ink_res_mm: float = bounded(0.05, lo=MIN_INK_RES_MM, hi=10, unit="mm",
                                why="the ink raster's pixel")
    # a run is "ok" only while its worst marking error stays within this many needle widths
    # (toolpath.needle_width_mm): within half a width the drawn line still covers the
    # centreline it was planned on (tattotronix/control/verdict.py)
    tolerance_needle_widths: float = bounded(
        0.5, lo=0, lo_open=True, hi=100, why="the marking tolerance, in needle widths")
    progress: bool = True  # a progress bar with simulated time and real-time factor



@settings
class HardwareConfig:
    """The real arm: the PCA9685 board, the servo calibration, and how a drawing is sent.

    ``servos`` is the calibration (board settings, per-joint channels and pulse mapping,
    the tool channel); it is validated by :mod:`tattotronix.hardware.servos`, which names
    the joint and key of every problem. ``calibration_file`` replaces it with a per-board
    file of the same shape.
    """

    # Any: OmegaConf 2.3 types no nested mapping of mixed values (it has no Union types)
    servos: dict[str, Any] = MISSING  # Any: OmegaConf (above); hardware/servos.py checks it
    calibration_file: str | None = None
    # the servos' figures identified from a photographed calibration sheet
    # (stages/calibrate.py photo=...; docs/servos.md, "Identification from a drawn sheet"):
    # a YAML file whose per-joint backlash and dead band replace the catalogue's, for the
    # corrections and the servo plant alike; null: the catalogue's
    servo_figures_file: str | None = None
    # the slow move to the start pose (and lifts), fastest joint
    ramp_rad_s: float = bounded(0.25, lo=0, lo_open=True, hi=10, unit="rad/s")
    state_file: str = "arm/state.json"  # under paths.data: last commanded pose, resume point
    # the state file is refreshed this often while drawing
    save_every_s: float = bounded(1.0, lo=0, lo_open=True, hi=3600, unit="s")
    # dry-run fault injection: the bus fails after N
    fail_after_writes: int | None = bounded(None, lo=0, hi=1_000_000_000)
    compensate: CompensateConfig = field(default_factory=CompensateConfig)


@settings
class KinematicsStudyConfig:
    """The kinematics study (docs/kinematics.md; docs/original.md, "3.4 Conditioning,
    reachability, placement"). Placements pair widths[i] with offsets[i]."""

    # the reachability grid over the panel (the original's: 33 x 23)
    reach_nx: int = bounded(33, lo=2, hi=200)
    reach_ny: int = bounded(23, lo=2, hi=200)
    placement_widths_mm: list[float] = bounded(
        factory=lambda: [120.0, 150.0, 120.0, 100.0, 150.0, 120.0, 150.0, 150.0], lo=0,
        lo_open=True, hi=1000, unit="mm")
    placement_offsets_mm: list[float] = bounded(
        factory=lambda: [0.0, 0.0, 15.0, 30.0, 15.0, 30.0, 30.0, 45.0], lo=-1000, hi=1000,
        unit="mm")
    workspace_samples: int = bounded(60_000, lo=1, hi=1_000_000)
    workspace_seed: int = bounded(0, lo=0, hi=2**32 - 1)


@settings
class ControlCase:
    """One run of the control study: a controller structure at a bandwidth."""

    structure: Structure = MISSING
    wn: float = bounded(MISSING, lo=0.1, hi=10_000, unit="rad/s")


@settings
class ControlStudyConfig:
    """The control study (docs/control.md, "The control study: whole drawing and busiest
    window"; docs/original.md, "5.6 Published control results"): structures at wn 20, and
    a wn sweep.

    ``cases`` maps a run's name (``<structure>-wn<wn>``) to its controller; each runs over
    the whole drawing and over its busiest ``window_s`` window.
    """

    cases: dict[str, ControlCase] = MISSING


@settings
class ServoCase:
    """One run of the servo study (docs/servos.md, "The servo study"): which servos, which
    corrections, at which speed; ``only`` keeps one imperfection of the servo plant
    (``quantise``, ``deadband``, ``backlash``, ``nonlinearity`` or ``lag``) and switches
    the others off."""

    type: str | None = None  # a robot.servos name on every joint; null: as mounted
    fit: bool = False
    backlash: bool = False
    deadband: bool = False
    sag: bool = False
    lead: bool = False
    speed: float = bounded(1.0, lo=0.01, hi=1000)
    only: str | None = None


@settings
class ServoStudyConfig:
    """The servo study's cases: name -> :class:`ServoCase` (named as the study names it)."""

    cases: dict[str, ServoCase] = MISSING


@settings
class ServoSpreadConfig:
    """How far one servo of a catalogue type may be from its catalogue figures, +- % of
    each (uniform; each joint's servo drawn on its own): the robustness study's stated
    uncertainty (docs/servos.md, "Robustness"). A figure the catalogue marks as assumed
    gets +-50 %; a maker's figure, the spread of units and supply voltage."""

    deadband_pct: float = bounded(50.0, lo=0, hi=90, unit="%",
                                  why="a distributor's sheet, not the maker's")
    stall_pct: float = bounded(15.0, lo=0, hi=90, unit="%",
                               why="the maker's figure; the supply's sag and unit spread")
    speed_pct: float = bounded(15.0, lo=0, hi=90, unit="%",
                               why="the maker's figure; the supply's sag and unit spread")
    band_pct: float = bounded(50.0, lo=0, hi=90, unit="%", why="assumed")
    backlash_pct: float = bounded(50.0, lo=0, hi=90, unit="%", why="assumed")
    nonlinearity_pct: float = bounded(50.0, lo=0, hi=90, unit="%", why="assumed")
    armature_pct: float = bounded(50.0, lo=0, hi=90, unit="%", why="assumed")
    latency_pct: float = bounded(30.0, lo=0, hi=90, unit="%",
                                 why="half a frame is certain, the servo's own part is not")


@settings
class RobustnessStudyConfig:
    """The robustness study (docs/servos.md, "Robustness"): ``draws`` arms whose servos
    differ from the catalogue by ``spread``, each playing the study artwork's busiest
    window with no correction, each correction alone and all of them, the corrections
    sized from the catalogue (the program does not know the true servo; the pulse-map
    fit is measured on it, as a user measures their own)."""

    draws: int = bounded(128, lo=1, hi=100_000, why="arms drawn from the spread")
    seed: int = bounded(0, lo=0, hi=2**32 - 1)
    spread: ServoSpreadConfig = field(default_factory=ServoSpreadConfig)


@settings
class FillCase:
    """One fill style of the fill-styles comparison (``stages/fills.py``): the values of
    ``toolpath.fill_style`` and ``toolpath.fill_angle_deg`` it plans with."""

    fill_style: FillStyle = MISSING
    fill_angle_deg: float = bounded(0.0, lo=-180, hi=180, unit="deg",
                                    why="the hatch's angle from the x axis")


@settings
class FillsStudyConfig:
    """The fill styles side by side (docs/toolpath.md, "Fill styles"): each case is the
    study artwork planned again with its style, scored against the artwork; the figure
    shows a ``zoom_mm`` square of each, where the artwork is densest."""

    cases: dict[str, FillCase] = MISSING
    zoom_mm: float = bounded(12.0, lo=1, hi=1000, unit="mm", why="the side of each crop")


@settings
class ActuatorOption:
    """A way to drive the servos: how the pulse is stepped, and which joints are bus servos.

    ``command`` is ``pca9685`` (4096 counts per servo frame) or ``arduino`` (1 us steps).
    """

    name: str = MISSING
    command: str = MISSING
    bus_joints: list[str] = field(default_factory=list)


@settings
class ActuatorStudyConfig:
    """The actuator study (docs/actuators.md; docs/original.md, "6.6 The actuator study"):
    what hobby servos allow at the needle."""

    # every 5th marking point is a pose of the study
    every: int = bounded(5, lo=1, hi=1_000_000)
    # the declared pulse-to-angle scale (2000 us over 180 deg)
    us_per_deg: float = bounded(11.111, lo=0, lo_open=True, hi=1000, unit="us/deg")
    # the Arduino Servo library's pulse step
    arduino_step_us: float = bounded(1.0, lo=0, lo_open=True, hi=1000, unit="us")
    # a 12-bit encoder: 360 / 4096 deg
    bus_step_deg: float = bounded(0.087890625, lo=0, lo_open=True, hi=360, unit="deg")
    # "one degree of play at every joint"
    play_deg: float = bounded(1.0, lo=0, hi=90, unit="deg")
    # "every 0.1 deg of backlash costs up to ..."
    backlash_deg: float = bounded(0.1, lo=0, hi=90, unit="deg")
    options: list[ActuatorOption] = MISSING


@settings
class StudyConfig:
    """Settings of the study stages (each study is a sweep: see dvc.yaml and the README).

    The swept values are lists (``approach_mm``, ``step_mm``, ``rate_hz`` x ``wn``) or
    named cases (``control``); ``python stages/<study>.py -m key=a,b,c`` runs any other.
    """

    # the busiest window (the original reported on the busiest 12 s of a drawing)
    window_s: float = bounded(12.0, lo=0, lo_open=True, hi=1e5, unit="s")
    # run every configured case of the study, concurrently (the DVC stage); false: the one
    # case the settings describe (a hand run)
    all_cases: bool = False
    kinematics: KinematicsStudyConfig = field(default_factory=KinematicsStudyConfig)
    control: ControlStudyConfig = field(default_factory=ControlStudyConfig)
    # the same ranges as toolpath.approach_mm, toolpath.step_mm, controller.rate_hz,
    # controller.wn and plant.dt_s, whose values they sweep: stages/approach.py, the slow
    # last stretch of every plunge (docs/original.md, "5.7 The approach study");
    # stages/resample.py, the point step ("2.11 The resample study"); stages/rate.py, loop
    # rate x bandwidth with the plant at 4 kHz ("5.8 The rate study")
    approach_mm: list[float] = bounded(factory=lambda: [0.0, 0.5, 1.0, 2.0, 4.0], lo=0,
                                       hi=120, unit="mm")
    step_mm: list[float] = bounded(factory=lambda: [0.6, 0.3, 0.15], lo=MIN_STEP_MM,
                                   hi=100, unit="mm")
    rate_hz: list[int] = bounded(factory=lambda: [200, 500, 1000], lo=1, hi=10_000,
                                 unit="Hz")
    rate_wn: list[int] = bounded(factory=lambda: [40, 80, 160], lo=1, hi=10_000,
                                 unit="rad/s")
    # the rate study's plant step (4 kHz)
    rate_plant_dt_s: float = bounded(0.00025, lo=MIN_DT_S, hi=0.1, unit="s")
    # the time-law study: trajectory.tip_accel_mm_s2 x trajectory.jerk_rad_s3
    timelaw_tip_mm_s2: list[int] = bounded(factory=lambda: [100, 200, 400], lo=1,
                                           hi=1_000_000, unit="mm/s^2")
    timelaw_jerk_rad_s3: list[int] = bounded(factory=lambda: [500, 2000], lo=1,
                                             hi=1_000_000, unit="rad/s^3")
    actuator: ActuatorStudyConfig = field(default_factory=ActuatorStudyConfig)
    servo: ServoStudyConfig = field(default_factory=ServoStudyConfig)
    robustness: RobustnessStudyConfig = field(default_factory=RobustnessStudyConfig)
    fills: FillsStudyConfig = field(default_factory=FillsStudyConfig)


class SurfaceKind(Enum):
    """The work surface: the flat panel, the built-in forearm phantom, or a mesh file."""

    panel = "panel"
    forearm = "forearm"
    mesh = "mesh"


@settings
class PhantomConfig:
    """The forearm phantom: a tapered elliptic cylinder (docs/surface.md, "The phantom")."""

    length_mm: float = bounded(220.0, lo=10, hi=1000, unit="mm")
    elbow_width_mm: float = bounded(80.0, lo=5, hi=500, unit="mm")
    wrist_width_mm: float = bounded(55.0, lo=5, hi=500, unit="mm")
    depth_ratio: float = bounded(0.75, lo=0.2, hi=1.0,
                                 why="the section's thickness over its width")


@settings
class SurfaceConfig:
    """The work surface and where the design goes on it (docs/surface.md)."""

    kind: SurfaceKind = SurfaceKind.panel
    phantom: PhantomConfig = field(default_factory=PhantomConfig)
    # surface=mesh: an STL, PLY or OBJ file, its unit in mm (10: cm) and the placement
    # point in its own frame after the unit, mm (null: its highest point once posed)
    mesh_file: str | None = None
    mesh_unit_mm: float = bounded(1.0, lo=1e-3, hi=1000, why="millimetres per file unit")
    mesh_at_mm: list[float] | None = bounded(None, lo=-1000, hi=1000, unit="mm")
    # the limb's pose on the bench: its frame's origin (the phantom's: the elbow end of
    # its axis) in the arm frame, and its turn about the vertical (0: the limb pointing
    # away from the arm's base, along x; 90: across, along y)
    origin_mm: list[float] = bounded(factory=lambda: [60.0, 0.0, 30.0], lo=-1000,
                                     hi=1000, unit="mm")
    yaw_deg: float = bounded(0.0, lo=-360, hi=360, unit="deg")
    # the design's centre on the phantom: along its axis from the elbow end, around it
    # (90: the top), and the design's turn there (0: its width along the limb; 90:
    # around it)
    along_mm: float = bounded(150.0, lo=0, hi=1000, unit="mm")
    around_deg: float = bounded(90.0, lo=-360, hi=360, unit="deg")
    turn_deg: float = bounded(90.0, lo=-360, hi=360, unit="deg")
    # the most the map from the design to the skin may distort it (area or angle)
    max_distortion_pct: float = bounded(0.5, lo=0, hi=100, unit="%")
    # the tip's acceleration limit while marking on the skin (on the panel:
    # trajectory.tip_accel_mm_s2). The wrist turns the needle with the normal as it marks,
    # so every joint accelerates more per mm/s^2 of the tip than on the panel, and the
    # loop's error grows with it: chosen from a sweep on the built-in drawing around the
    # phantom (docs/surface.md, "The drawing simulated on the skin")
    tip_accel_mm_s2: float = bounded(50.0, lo=0, lo_open=True, hi=1e6, unit="mm/s^2")
    # the reachability map over the phantom: sections along it, points around each, and
    # the ends left out
    reach_along: int = bounded(23, lo=2, hi=500, why="sections of the reachability map")
    reach_around: int = bounded(36, lo=4, hi=720, why="points around each section")
    reach_margin_mm: float = bounded(10.0, lo=0, hi=500, unit="mm")

    @property
    def tip_accel_m_s2(self) -> float:
        """The tip's acceleration limit while marking on the skin, m/s^2."""
        return float(self.tip_accel_mm_s2) / 1000


@settings
class PathsConfig:
    """Where runs read and write (relative to the working folder; README, "Hand runs")."""

    data: str = PIPELINE_DATA  # every run reads here; dvc repro writes here
    out: str | None = None  # where a run writes; null: paths.data under DVC, runs/ by hand


@settings
class Config:
    """The composed configuration (``params.yaml``)."""

    paths: PathsConfig = field(default_factory=PathsConfig)
    robot: RobotConfig = MISSING
    artwork: ArtworkConfig = field(default_factory=ArtworkConfig)
    mask: MaskConfig = field(default_factory=MaskConfig)
    toolpath: ToolpathConfig = field(default_factory=ToolpathConfig)
    ik: IkConfig = field(default_factory=IkConfig)
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    collision: CollisionConfig = field(default_factory=CollisionConfig)
    study: StudyConfig = field(default_factory=StudyConfig)
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    plant: PlantConfig = field(default_factory=PlantConfig)
    draw: DrawConfig = field(default_factory=DrawConfig)
    servo: ServoPlantConfig = field(default_factory=ServoPlantConfig)
    surface: SurfaceConfig = field(default_factory=SurfaceConfig)
    # rescales the motion: 2 draws twice as fast (marking at 2x feed)
    speed: float = bounded(1.0, lo=0.01, hi=1000)
    backend: Backend = Backend.mujoco  # draw.py: the plant
    art: str | None = None  # draw.py: a stored (or built-in) drawing by name
    # draw.py: null (whole drawing), [start_s, length_s] or "busiest"
    window: Any = None  # Any: OmegaConf 2.3 has no Union (of a list and a str)
    viewer: bool = False  # draw.py: watch the run where a display exists
    hardware: HardwareConfig = field(default_factory=HardwareConfig)
    dry_run: bool = False  # backend=arm: a recording bus instead of the I2C device
    preview: bool = False  # backend=arm: print the plan, write preview.png, send nothing
    resume: bool = False  # backend=arm: continue a paused or failed drawing
    realtime: bool = True  # backend=arm dry run: stream at the frame rate (false: at once)
    # collision.py: report this one pose (rad) as JSON
    pose: list[float] | None = bounded(None, lo=-TURN, hi=TURN, unit="rad")


SCHEMAS: dict[str, type] = {
    "robot": RobotConfig,
    "artwork": ArtworkConfig,
    "mask": MaskConfig,
    "toolpath": ToolpathConfig,
    "ik": IkConfig,
    "trajectory": TrajectoryConfig,
    "collision": CollisionConfig,
    "study": StudyConfig,
    "controller": ControllerConfig,
    "plant": PlantConfig,
    "draw": DrawConfig,
    "servo": ServoPlantConfig,
    "hardware": HardwareConfig,
    "surface": SurfaceConfig,
}


def register() -> None:
    """Register the schemas in Hydra's ConfigStore (idempotent).

    Each group's schema is stored as ``<group>/_schema``; the root as ``_config_schema``.
    """
    from hydra.core.config_store import ConfigStore  # here: a stage run by DVC needs no Hydra

    cs = ConfigStore.instance()
    for group, node in SCHEMAS.items():
        cs.store(group=group, name="_schema", node=node)
    cs.store(name="_config_schema", node=Config)
