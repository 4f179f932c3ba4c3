"""Typed schemas of every Hydra config group (dataclasses registered in the ConfigStore).

The YAML files under ``conf/`` hold values only; these dataclasses hold the keys and their
types. Every group file names its schema first in its defaults list, so a typo or a bad
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
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import FrozenInstanceError, dataclass, field
from enum import Enum
from typing import Any, TypeAlias, TypeVar, dataclass_transform

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

__all__ = [
    "ActuatorOption",
    "ActuatorStudyConfig",
    "ArtworkConfig",
    "Backend",
    "BenchConfig",
    "BoxInertial",
    "CollisionConfig",
    "Config",
    "ControlCase",
    "ControlStudyConfig",
    "ControllerConfig",
    "DrawConfig",
    "FrameConfig",
    "HardwareConfig",
    "IkConfig",
    "InertialConfig",
    "JointConfig",
    "KinematicsStudyConfig",
    "MaskConfig",
    "MaskMethod",
    "MassModel",
    "PanelConfig",
    "PathsConfig",
    "PenConfig",
    "Plain",
    "PlantConfig",
    "RobotConfig",
    "ServoConfig",
    "ServoMountConfig",
    "Structure",
    "StudyConfig",
    "Tool",
    "ToolpathConfig",
    "TrajectoryConfig",
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


@settings
class JointConfig:
    """One revolute joint: fixed origin (parent frame, m / rad), then a rotation about ``axis``."""

    name: str = MISSING
    parent: str = MISSING
    child: str = MISSING
    xyz: list[float] = MISSING
    rpy: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    axis: list[float] = MISSING
    lower: float = MISSING  # rad
    upper: float = MISSING  # rad
    effort: float = 20.0  # N m
    velocity: float = 1.5  # rad/s


@settings
class FrameConfig:
    """A frame rigidly attached to ``parent`` (no body of its own)."""

    name: str = MISSING
    parent: str = MISSING
    xyz: list[float] = MISSING
    rpy: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])


@settings
class InertialConfig:
    """Mass (kg), CoM in the link frame (m) and inertia about the CoM in link axes (kg m^2).

    ``inertia`` is ``[ixx, ixy, ixz, iyy, iyz, izz]``.
    """

    mass: float = MISSING
    com: list[float] = MISSING
    inertia: list[float] = MISSING


@settings
class BoxInertial:
    """The ``box`` mass model for one link: a solid box of the link's bounding box.

    Its ``centre`` and ``size`` (m) also size the primitive geometry used without meshes.
    """

    mass: float = MISSING
    centre: list[float] = MISSING
    size: list[float] = MISSING


@settings
class PenConfig:
    """The placeholder tattoo pen on ``tool0``: a cylinder along tool0 +z (m, kg)."""

    length: float = 0.045
    radius: float = 0.003
    mass: float = 0.020
    barrel_length: float = 0.037  # visual barrel; the rest is the tip cone


@settings
class PanelConfig:
    """The work panel in the arm frame (m). Visual only: the needle may enter it."""

    centre: list[float] = field(default_factory=lambda: [0.21, 0.0, 0.0025])
    size: list[float] = field(default_factory=lambda: [0.20, 0.14, 0.005])

    @property
    def size_mm(self) -> tuple[float, float]:
        """Width and height of the panel, mm."""
        return float(self.size[0]) * 1e3, float(self.size[1]) * 1e3


@settings
class BenchConfig:
    """The bench under the arm (m); its top is the arm frame's z = 0."""

    size: list[float] = field(default_factory=lambda: [0.70, 0.50, 0.75])


@settings
class ServoConfig:
    """A catalogue hobby servo: mass (kg), body box (m), dead band (us)."""

    mass: float = MISSING
    size: list[float] = MISSING
    deadband_us: float = MISSING


@settings
class ServoMountConfig:
    """Where a servo sits: on ``link``, centred on joint ``at`` (or ``tool`` axis)."""

    link: str = MISSING
    servo: str = MISSING
    at: str = MISSING  # a joint name, or "tool" for the tool servo on the tool axis
    count: int = 1


@settings
class RobotConfig:
    """The one robot description: URDF, MJCF and every loader are generated from it."""

    name: str = "tattotronix"
    base_link: str = "base_link"
    joints: list[JointConfig] = MISSING
    tool0: FrameConfig = MISSING
    tcp: FrameConfig = MISSING
    tool: Tool = Tool.tattoo
    pen: PenConfig = field(default_factory=PenConfig)
    mass_model: MassModel = MassModel.printed
    printed: dict[str, InertialConfig] = MISSING
    box: dict[str, BoxInertial] = MISSING
    cad_dir: str | None = None
    mesh_scale: float = 0.01  # the CAD meshes are in centimetres
    gravity: float = 9.80665  # m/s^2
    bench: BenchConfig = field(default_factory=BenchConfig)
    panel: PanelConfig = field(default_factory=PanelConfig)
    # mass integration (the ``mass`` stage)
    pla_density: float = 1240.0  # kg/m^3, solid PLA
    printed_fraction: float = 0.35  # share of solid: 20 % infill, perimeters dominate
    servos: dict[str, ServoConfig] = MISSING
    servo_mounts: list[ServoMountConfig] = MISSING


@settings
class ArtworkConfig:
    """Which artwork to draw. ``source`` null means the built-in emblem."""

    source: str | None = None
    name: str | None = None  # defaults to the file's stem
    max_pixels: int = 40_000_000  # refuse larger images (decompression bombs)


@settings
class MaskConfig:
    """Artwork to ink mask."""

    width_mm: float = 150.0
    res_mm: float = 0.25
    method: MaskMethod = MaskMethod.threshold
    min_region_mm2: float = 4.0
    edge_sigma_px: float = 2.0
    edge_k: float = 1.0


@settings
class ToolpathConfig:
    """Mask to ordered needle path (mm in the panel plane)."""

    pitch_mm: float = 1.2
    step_mm: float = 0.15
    clearance_mm: float = 8.0
    plunge_mm: float = 1.5
    approach_mm: float = 2.0
    min_loop_px: int = 8
    feed_mark_mm_s: float = 6.0
    feed_travel_mm_s: float = 60.0
    lift_s: float = 0.0  # extra fixed cost per needle entry in the ordering objective
    outlines_first: bool = True
    panel_origin: list[float] = field(default_factory=lambda: [0.21, 0.0, 0.005])  # m

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

    dls_lambda: float = 1e-3  # the damped-least-squares lambda, added to J J^T as is
    max_iter: int = 200
    tol: float = 1e-6  # |e|, mixed m / unitless
    seed: list[float] = field(default_factory=lambda: [0.0, 0.6, -0.9, 0.0, -1.2])  # rad
    needle_axis: list[float] = field(default_factory=lambda: [0.0, 0.0, -1.0])
    anchor_spacing_m: float = 0.005  # batched solver: an anchor every 5 mm of path
    verify_pos_tol_m: float = 2e-6
    verify_axis_tol_rad: float = 2e-6


@settings
class TrajectoryConfig:
    """Time law along the IK path: feeds, joint limits, ramps.

    Marking and approach run at ``toolpath.feed_mark_mm_s``; joint velocity limits come
    from the robot's joint table. ``speed`` (root key) rescales the whole motion.
    """

    travel_feed_mm_s: float = 200.0  # cap on the tip speed of travel moves
    accel_rad_s2: float = 10.0  # per-joint acceleration limit (see conf/trajectory)
    jerk_rad_s3: float | None = None  # jerk limits are not implemented: must be null
    max_step_mm: float = 0.5  # longer segments (travel, lifts) get points on the tip line
    travel: str = "planned"  # planned: joint-space moves between strokes; straight: tip lines
    home: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 0.0, 0.0])  # rad
    from_home: bool = True  # planned travel: start at home and return home
    lifts_mm: list[float] = field(default_factory=lambda: [10.0, 20.0, 40.0, 80.0])

    @property
    def travel_feed_m_s(self) -> float:
        """The cap on the tip speed of travel moves, m/s."""
        return float(self.travel_feed_mm_s) / 1000

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

    margin_mm: float = 1.0  # least clearance a trajectory and a planned move must keep
    resolution_mm: float = 0.1  # bisect the motion between samples down to this bound

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
    arm = "arm"


@settings
class ControllerConfig:
    """The joint controller shared by every plant (docs/control.md, "The controller";
    docs/original.md, "5.2 Controller structure" and "5.3 Tuning by pole placement").

    PID by pole placement on the effective inertia J_eff at ``tune_q`` (all three poles
    at -wn): Kp = 3 J wn^2, Kd = 3 J wn, Ki = J wn^3.
    """

    structure: Structure = Structure.pid_g_v
    wn: float = 160.0  # rad/s, one bandwidth for every joint
    rate_hz: float = 1000.0  # the loop runs at this rate, zero-order hold between ticks
    torque_limit_nm: float | None = None  # null: each joint's effort limit (20 N m)
    tune_q: list[float] | None = None  # rad; null: the reference pose mid-way through the run


@settings
class PlantConfig:
    """The simulated arm, whichever backend runs it."""

    dt_s: float = 0.001  # integration step (semi-implicit Euler in every backend)
    damping: float = 0.0  # viscous joint friction, N m s/rad (none unless configured)
    joint_limits: bool = False  # enforce the joint range (the model plant clamps)
    contacts: bool = False  # arm-bench contact (MuJoCo, PyBullet); the panel never resists
    abort_error_rad: float = 1.0  # a joint this far from its reference: the run diverged


@settings
class DrawConfig:
    """Error bookkeeping and the ink image of a simulated drawing (docs/original.md, "5.5
    Tracking error"; docs/control.md, "Ink against the plan")."""

    sample_s: float = 0.02  # tracking error sampled every 20 ms
    settle_periods: float = 4.0  # "settled" excludes settle_periods / wn after each entry
    needle_mm: float = 0.3  # ink line width
    ink_res_mm: float = 0.05  # ink raster pixel
    progress: bool = True  # a progress bar with simulated time and real-time factor

    @property
    def needle_um(self) -> float:
        """The ink line width, um."""
        return float(self.needle_mm) * 1e3


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
    ramp_rad_s: float = 0.25  # the slow move to the start pose (and lifts), fastest joint
    state_file: str = "arm/state.json"  # under paths.data: last commanded pose, resume point
    save_every_s: float = 1.0  # the state file is refreshed this often while drawing
    fail_after_writes: int | None = None  # dry-run fault injection: the bus fails after N


@settings
class KinematicsStudyConfig:
    """The kinematics study (docs/kinematics.md; docs/original.md, "3.4 Conditioning,
    reachability, placement"). Placements pair widths[i] with offsets[i]."""

    reach_nx: int = 33
    reach_ny: int = 23
    placement_widths_mm: list[float] = field(
        default_factory=lambda: [120.0, 150.0, 120.0, 100.0, 150.0, 120.0, 150.0, 150.0])
    placement_offsets_mm: list[float] = field(
        default_factory=lambda: [0.0, 0.0, 15.0, 30.0, 15.0, 30.0, 30.0, 45.0])
    workspace_samples: int = 60_000
    workspace_seed: int = 0


@settings
class ControlCase:
    """One run of the control study: a controller structure at a bandwidth."""

    structure: Structure = MISSING
    wn: float = MISSING


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

    every: int = 5  # every 5th marking point is a pose of the study
    us_per_deg: float = 11.111  # the declared pulse-to-angle scale (2000 us over 180 deg)
    arduino_step_us: float = 1.0  # the Arduino Servo library's pulse step
    bus_step_deg: float = 0.087890625  # a 12-bit encoder: 360 / 4096 deg
    play_deg: float = 1.0  # "one degree of play at every joint"
    backlash_deg: float = 0.1  # "every 0.1 deg of backlash costs up to ..."
    options: list[ActuatorOption] = MISSING


@settings
class StudyConfig:
    """Settings of the study stages (each study is a sweep: see dvc.yaml and the README).

    The swept values are lists (``approach_mm``, ``step_mm``, ``rate_hz`` x ``wn``) or
    named cases (``control``); ``python stages/<study>.py -m key=a,b,c`` runs any other.
    """

    window_s: float = 12.0  # the original's "busiest window" length
    kinematics: KinematicsStudyConfig = field(default_factory=KinematicsStudyConfig)
    control: ControlStudyConfig = field(default_factory=ControlStudyConfig)
    approach_mm: list[float] = field(default_factory=lambda: [0.0, 0.5, 1.0, 2.0, 4.0])
    step_mm: list[float] = field(default_factory=lambda: [0.6, 0.3, 0.15])
    rate_hz: list[int] = field(default_factory=lambda: [200, 500, 1000])
    rate_wn: list[int] = field(default_factory=lambda: [40, 80, 160])
    rate_plant_dt_s: float = 0.00025  # the rate study's plant step (4 kHz)
    actuator: ActuatorStudyConfig = field(default_factory=ActuatorStudyConfig)


@settings
class PathsConfig:
    """Where outputs go. Relative paths are taken from the project root."""

    data: str = "data"


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
    speed: float = 1.0  # rescales the motion: 2 draws twice as fast (marking at 2x feed)
    backend: Backend = Backend.mujoco  # draw.py: the plant
    art: str | None = None  # draw.py: a stored (or built-in) drawing by name
    # draw.py: null (whole drawing), [start_s, length_s] or "busiest"
    window: Any = None  # Any: OmegaConf 2.3 has no Union (of a list and a str)
    viewer: bool = False  # draw.py: watch the run where a display exists
    hardware: HardwareConfig = field(default_factory=HardwareConfig)
    dry_run: bool = False  # backend=arm: a recording bus instead of the I2C device
    resume: bool = False  # backend=arm: continue a paused or failed drawing
    realtime: bool = True  # backend=arm dry run: stream at the frame rate (false: at once)
    pose: list[float] | None = None  # collision.py: report this one pose (rad) as JSON


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
    "hardware": HardwareConfig,
}


def register() -> None:
    """Register the schemas in Hydra's ConfigStore (idempotent).

    Each group's schema is stored as ``<group>/_schema``; the root as ``_config_schema``.
    """
    cs = ConfigStore.instance()
    for group, node in SCHEMAS.items():
        cs.store(group=group, name="_schema", node=node)
    cs.store(name="_config_schema", node=Config)
