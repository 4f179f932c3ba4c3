"""Load the generated models in Pinocchio, MuJoCo and PyBullet behind one small interface.

Each loader answers the same three questions at a joint configuration ``q`` (rad):
where every named frame is (m, arm frame), the joint-space mass matrix (kg m^2) and the
gravity torques (N m). Tests hold the three to each other; the plants build on them.
Gravity is the description's value (9.80665 m/s^2) in every loader.

Pinocchio's model of a URDF is built once per process (:func:`pinocchio_model`) and shared
by every user (:class:`PinocchioArm`, ``PinocchioTip`` in tattotronix/kinematics/ik.py,
``Dynamics`` in tattotronix/control/dynamics.py, ``ModelPlant`` in
tattotronix/plants/model.py and ``CollisionModel`` in tattotronix/collision/model.py).
The shared ``pinocchio.Model`` is read-only; each user makes its own ``pinocchio.Data``.

The model files are the ``robot`` stage's outputs (``data/robot/<name>.urdf`` and
``.xml``): every reader here refuses a missing, truncated or foreign file with a
:class:`~tattotronix.errors.TattotronixError` that names the file and the stage to re-run
(:func:`read_model`, :func:`model_refused`).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import sys
import tempfile
import threading
from collections import OrderedDict
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from tattotronix.errors import StageInputMissing, TattotronixError

__all__ = ["STANDARD_GRAVITY", "ArmModel", "MujocoArm", "PinocchioArm", "PybulletArm",
           "load_mujoco", "load_mujoco_spec", "load_pinocchio", "load_pybullet", "model_refused",
           "pinocchio_model",
           "read_model"]

#: the stage that writes the model files
MODEL_STAGE = "robot"

#: m/s^2: the description's default gravity (``robot.gravity``), the one the
#: kinematics-only users of :func:`pinocchio_model` ask for when they are not told one
STANDARD_GRAVITY = 9.80665

Vec = NDArray[np.float64]


class ArmModel(Protocol):
    """What every loader can tell about the arm."""

    joint_names: tuple[str, ...]

    def frames(self, q: Vec) -> dict[str, Vec]:
        """Position of every named frame (m)."""
        ...

    def mass_matrix(self, q: Vec) -> Vec:
        """Joint-space mass matrix (n, n), kg m^2."""
        ...

    def gravity(self, q: Vec) -> Vec:
        """Gravity torques (n,), N m: the torque that holds the arm still at ``q``."""
        ...


# (sha256 of the URDF text, gravity) -> pinocchio.Model, least recently used first
_MODELS: OrderedDict[tuple[str, float], Any] = OrderedDict()
_MODELS_LOCK = threading.Lock()
#: most models kept (a sweep over descriptions makes one per variant)
_MODELS_MAX = 64


def pinocchio_model(urdf_text: str, gravity: float = STANDARD_GRAVITY
                    ) -> Any:  # Any: a pin.Model (pinocchio ships no type stubs)
    """The process's one Pinocchio model of this URDF: fixed base, ``gravity`` (m/s^2)
    along -z.

    Built on the first call and shared by every later one with the same text and gravity
    (keyed by the text's sha256, so an edited URDF is built anew). The model is shared,
    so it is **read-only**: make per-user state with ``model.createData()``, and copy it
    (``pinocchio.Model(model)``) before changing anything on it.
    """
    key = (hashlib.sha256(urdf_text.encode("utf-8")).hexdigest(), float(gravity))
    with _MODELS_LOCK:
        model = _MODELS.get(key)
        if model is not None:
            _MODELS.move_to_end(key)
            return model
        import pinocchio as pin

        model = pin.buildModelFromXML(urdf_text)
        model.gravity.linear = np.array([0.0, 0.0, -float(gravity)])
        _MODELS[key] = model
        if len(_MODELS) > _MODELS_MAX:
            _MODELS.popitem(last=False)
        return model


def model_refused(path: str | Path, why: str) -> TattotronixError:
    """The error for a model file (URDF, MJCF) that cannot be used: what is wrong, and
    which stage writes it."""
    return TattotronixError(f"cannot read {path} ({' '.join(why.split())}): re-run the "
                            f"'{MODEL_STAGE}' stage (python stages/{MODEL_STAGE}.py)")


def read_model(path: str | Path) -> str:
    """The text of a model file the ``robot`` stage wrote.

    Raises:
        TattotronixError: the file is missing (run the ``robot`` stage) or unreadable.
    """
    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise StageInputMissing(Path(path), MODEL_STAGE) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise model_refused(path, f"{type(exc).__name__}: {exc}") from None


@contextlib.contextmanager
def _c_stderr() -> Iterator[list[str]]:
    """Hold back what C++ code writes straight to file descriptor 2 (urdfdom prints its
    parse errors there) and hand it over in the yielded list; the caller says it once."""
    said: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as held:
        os.dup2(held.fileno(), 2)
        try:
            yield said
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            held.seek(0)
            said.append(held.read().decode("utf-8", "replace"))


def load_pinocchio(urdf: Path, gravity: float) -> Any:  # Any: pin.Model (no stubs)
    """The shared, read-only Pinocchio model of the URDF file (its content, see
    :func:`pinocchio_model`), fixed base, with the description's gravity.

    Raises:
        TattotronixError: the file is missing, or is not a URDF Pinocchio can build (the
            message names it and the ``robot`` stage).
    """
    text = read_model(urdf)
    try:
        with _c_stderr() as said:
            model = pinocchio_model(text, gravity)
    except Exception as exc:  # pinocchio's parser raises ValueError, RuntimeError, ...
        detail = " ".join("".join(said).split()).split(" at line ")[0]
        detail = detail.removeprefix("Error: ")[:160]
        raise model_refused(urdf, f"not a URDF Pinocchio can read: {exc}"
                            + (f" {detail}" if detail else "")) from None
    if said and said[0]:
        sys.stderr.write(said[0])  # warnings of a model that loaded: as they were
    return model


def load_mujoco(mjcf: Path) -> Any:  # Any: mujoco.MjModel
    """The MuJoCo model of the MJCF file.

    Raises:
        TattotronixError: the file is missing, or is not an MJCF MuJoCo can compile (the
            message names it and the ``robot`` stage).
    """
    import mujoco

    read_model(mjcf)  # missing or unreadable: named as such
    try:
        return mujoco.MjModel.from_xml_path(str(mjcf))
    except Exception as exc:  # mujoco raises ValueError for bad XML, and others
        raise model_refused(mjcf, f"not an MJCF MuJoCo can read: {exc}") from None


def load_mujoco_spec(mjcf: Path) -> Any:  # Any: mujoco.MjSpec
    """The editable MuJoCo spec of the MJCF file (as :func:`load_mujoco`, before compiling).

    Raises:
        TattotronixError: as :func:`load_mujoco`.
    """
    import mujoco

    read_model(mjcf)
    try:
        return mujoco.MjSpec.from_file(str(mjcf))
    except Exception as exc:
        raise model_refused(mjcf, f"not an MJCF MuJoCo can read: {exc}") from None


class PinocchioArm:
    """Pinocchio: FK for every frame, CRBA and RNEA gravity (the shared model, its own
    ``Data``)."""

    def __init__(self, urdf: Path, gravity: float):
        import pinocchio as pin

        self._pin = pin
        self.model = load_pinocchio(urdf, gravity)
        self.data = self.model.createData()
        self.joint_names = tuple(self.model.names[1:])
        # Every frame once: links appear as BODY frames, fixed-joint children too.
        seen: dict[str, int] = {}
        for i, f in enumerate(self.model.frames):
            if f.type == pin.FrameType.BODY and f.name not in seen:
                seen[f.name] = i
        self._frame_ids = seen

    def frames(self, q: Vec) -> dict[str, Vec]:
        pin = self._pin
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return {n: self.data.oMf[i].translation.copy() for n, i in self._frame_ids.items()}

    def mass_matrix(self, q: Vec) -> Vec:
        m = self._pin.crba(self.model, self.data, np.asarray(q, dtype=float))
        return np.triu(m) + np.triu(m, 1).T

    def gravity(self, q: Vec) -> Vec:
        q = np.asarray(q, dtype=float)
        return self._pin.computeGeneralizedGravity(self.model, self.data, q).copy()


class MujocoArm:
    """MuJoCo: bodies and sites from the MJCF; ``mj_fullM`` and the bias force at rest."""

    def __init__(self, mjcf: Path):
        import mujoco

        self._mj = mujoco
        self.model = load_mujoco(mjcf)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.joint_names = tuple(
            mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(m.njnt)
        )
        self._bodies = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, i): i
                        for i in range(1, m.nbody)}
        self._sites = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SITE, i): i
                       for i in range(m.nsite)}

    def _set(self, q: Vec) -> None:
        self.data.qpos[:] = q
        self.data.qvel[:] = 0.0
        self._mj.mj_forward(self.model, self.data)

    def frames(self, q: Vec) -> dict[str, Vec]:
        self._set(q)
        out = {n: self.data.xpos[i].copy() for n, i in self._bodies.items()}
        out.update({n: self.data.site_xpos[i].copy() for n, i in self._sites.items()})
        return out

    def mass_matrix(self, q: Vec) -> Vec:
        self._set(q)
        full = np.zeros((self.model.nv, self.model.nv))
        self._mj.mj_fullM(self.model, self.data, full)
        return full

    def gravity(self, q: Vec) -> Vec:
        self._set(q)
        return self.data.qfrc_bias.copy()  # at zero velocity: gravity only


def import_pybullet() -> ModuleType:
    """``import pybullet``, without the "pybullet build time: ..." line its C module prints
    on stdout at import (it lands in the middle of a progress bar, or of a stage's JSON on
    stdout)."""
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            import pybullet
    finally:
        os.dup2(saved, 1)
        os.close(saved)
    return pybullet


class PybulletArm:
    """PyBullet (DIRECT): the URDF with its own inertias (``URDF_USE_INERTIA_FROM_FILE``)."""

    def __init__(self, urdf: Path, gravity: float):
        p = import_pybullet()
        self._p = p
        self.client = p.connect(p.DIRECT)
        p.setGravity(0, 0, -gravity, physicsClientId=self.client)
        self.body = load_pybullet(p, urdf, self.client)
        self._links: dict[str, int] = {
            p.getBodyInfo(self.body, physicsClientId=self.client)[0].decode(): -1
        }
        self._movable: list[int] = []
        names = []
        for i in range(p.getNumJoints(self.body, physicsClientId=self.client)):
            info = p.getJointInfo(self.body, i, physicsClientId=self.client)
            self._links[info[12].decode()] = i
            if info[2] == p.JOINT_REVOLUTE:
                self._movable.append(i)
                names.append(info[1].decode())
        self.joint_names = tuple(names)

    def close(self) -> None:
        """Disconnect the physics client."""
        if self._p.isConnected(self.client):
            self._p.disconnect(self.client)

    def _set(self, q: Vec) -> None:
        for idx, v in zip(self._movable, q, strict=True):
            self._p.resetJointState(self.body, idx, float(v), 0.0, physicsClientId=self.client)

    def frames(self, q: Vec) -> dict[str, Vec]:
        p = self._p
        self._set(q)
        out: dict[str, Vec] = {}
        for name, idx in self._links.items():
            if idx < 0:  # the base reports its inertial frame: step back to the link frame
                pos, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
                local = p.getDynamicsInfo(self.body, -1, physicsClientId=self.client)[3:5]
                inv = p.invertTransform(*local)
                out[name] = np.asarray(p.multiplyTransforms(pos, orn, *inv)[0], dtype=float)
            else:
                st = p.getLinkState(self.body, idx, computeForwardKinematics=True,
                                    physicsClientId=self.client)
                out[name] = np.asarray(st[4], dtype=float)  # URDF link frame
        return out

    def mass_matrix(self, q: Vec) -> Vec:
        m = self._p.calculateMassMatrix(self.body, [float(v) for v in q],
                                        physicsClientId=self.client)
        return np.asarray(m, dtype=float)

    def gravity(self, q: Vec) -> Vec:
        zero = [0.0] * len(q)
        tau = self._p.calculateInverseDynamics(self.body, [float(v) for v in q], zero, zero,
                                               physicsClientId=self.client)
        return np.asarray(tau, dtype=float)


def load_pybullet(p: Any, urdf: Path, client: int) -> int:  # Any: the pybullet module
    """Load the URDF file into PyBullet's ``client`` (fixed base, the file's inertias);
    its body id.

    Raises:
        TattotronixError: the file is missing, or PyBullet cannot load it (the message names
            it and the ``robot`` stage).
    """
    read_model(urdf)  # missing or unreadable: named as such
    try:
        return int(p.loadURDF(str(urdf), useFixedBase=True,
                              flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client))
    except p.error as exc:
        raise model_refused(urdf, f"not a URDF PyBullet can read: {exc}") from None
