"""One Pinocchio model per URDF per process (``pinocchio_model`` in
tattotronix/robot/loaders.py): its five users share the model, each has its own ``Data``,
an edited URDF is built anew, nothing changes the shared model, and every result is the
one an independently loaded model gives, to the last bit.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from tattotronix.collision import model as collision_model
from tattotronix.collision.model import CollisionModel
from tattotronix.control.dynamics import Dynamics
from tattotronix.kinematics import PinocchioTip
from tattotronix.plants.base import PlantSettings
from tattotronix.plants.model import ModelPlant
from tattotronix.robot.description import RobotDescription
from tattotronix.robot.loaders import (
    STANDARD_GRAVITY,
    PinocchioArm,
    load_pinocchio,
    pinocchio_model,
)
from tattotronix.robot.urdf import to_urdf

pin = pytest.importorskip("pinocchio")

Array = NDArray[np.float64]


def _independent(urdf: Path, gravity: float | None) -> Any:
    """A model of its own, loaded the way the users did before sharing: from the file,
    with ``gravity`` along -z (None: Pinocchio's default, as the IK and collision models
    had)."""
    model = pin.buildModelFromUrdf(str(urdf))
    if gravity is not None:
        model.gravity.linear = np.array([0.0, 0.0, -gravity])
    return model


def _poses(desc: RobotDescription) -> Array:
    rng = np.random.default_rng(7)
    return np.vstack([np.zeros(len(desc.joints)),
                      rng.uniform(desc.lower, desc.upper, (4, len(desc.joints)))])


def _users(desc: RobotDescription, urdf: Path) -> dict[str, Any]:
    settings = PlantSettings(dt_s=0.001, damping=0.0, joint_limits=False, contacts=False,
                             gravity=desc.gravity, tip_frame=desc.tip_frame)
    return {
        "arm": PinocchioArm(urdf, desc.gravity),
        "tip": PinocchioTip.from_description(desc),
        "dynamics": Dynamics(urdf, desc.gravity),
        "plant": ModelPlant(urdf, settings, lower=desc.lower, upper=desc.upper),
        "collision": CollisionModel(desc),
    }


def test_the_five_users_share_one_model_and_own_their_data(
        desc: RobotDescription, models: tuple[Path, Path]) -> None:
    urdf = models[0]
    users = _users(desc, urdf)
    shared = users["arm"].model
    assert all(u.model is shared for u in users.values())
    assert pinocchio_model(to_urdf(desc), desc.gravity) is shared
    assert load_pinocchio(urdf, desc.gravity) is shared
    assert PinocchioTip.from_urdf(urdf, desc.tip_frame, gravity=desc.gravity).model is shared
    # a second set of users shares it too, each with new Data
    again = _users(desc, urdf)
    assert all(u.model is shared for u in again.values())
    datas = [u.data for group in (users, again) for k, u in group.items() if k != "tip"]
    assert len({id(d) for d in datas}) == len(datas)
    assert np.array_equal(shared.gravity.linear, [0.0, 0.0, -desc.gravity])


def test_same_text_elsewhere_is_shared_an_edited_urdf_is_built_anew(
        desc: RobotDescription, tmp_path: Path) -> None:
    text = to_urdf(desc)
    a, b = tmp_path / "a.urdf", tmp_path / "b.urdf"
    a.write_text(text)
    b.write_text(text)
    first = load_pinocchio(a, desc.gravity)
    assert load_pinocchio(b, desc.gravity) is first

    mass = re.search(r'<mass value="([^"]+)"/>', text.split("<link", 2)[2])
    assert mass is not None and float(mass.group(1)) > 0
    edited = text.replace(mass.group(0), f'<mass value="{float(mass.group(1)) * 2!r}"/>', 1)
    assert edited != text
    a.write_text(edited)
    second = load_pinocchio(a, desc.gravity)
    assert second is not first
    assert second != first
    assert second == _independent(a, desc.gravity)
    assert load_pinocchio(b, desc.gravity) is first  # the unedited file keeps its model

    other = load_pinocchio(b, 1.625)  # another gravity: another model of the same text
    assert other is not first
    assert np.array_equal(other.gravity.linear, [0.0, 0.0, -1.625])
    assert np.array_equal(first.gravity.linear, [0.0, 0.0, -desc.gravity])


def test_tip_without_gravity_takes_the_standard_model(
        desc: RobotDescription, models: tuple[Path, Path]) -> None:
    tip = PinocchioTip.from_urdf(models[0], desc.tip_frame)
    assert tip.model is pinocchio_model(to_urdf(desc))
    assert np.array_equal(tip.model.gravity.linear, [0.0, 0.0, -STANDARD_GRAVITY])


def test_results_equal_an_independent_model_to_the_last_bit(
        desc: RobotDescription, models: tuple[Path, Path],
        monkeypatch: pytest.MonkeyPatch) -> None:
    urdf = models[0]
    users = _users(desc, urdf)
    shared = users["arm"].model
    ref = _independent(urdf, desc.gravity)
    ref_data = ref.createData()
    assert ref == shared
    poses = _poses(desc)
    rng = np.random.default_rng(11)

    arm, dyn, tip = users["arm"], users["dynamics"], users["tip"]
    body = {f.name: i for i, f in enumerate(ref.frames) if f.type == pin.FrameType.BODY}
    for q in poses:
        qd, qdd, tau = (rng.normal(size=len(q)) for _ in range(3))
        pin.framesForwardKinematics(ref, ref_data, q)
        want = {n: ref_data.oMf[i].translation.copy() for n, i in body.items()}
        got = arm.frames(q)
        assert got.keys() == want.keys()
        assert all(np.array_equal(got[n], want[n]) for n in want)
        m = pin.crba(ref, ref_data, q)
        m = np.triu(m) + np.triu(m, 1).T
        g = pin.computeGeneralizedGravity(ref, ref_data, q).copy()
        for user in (arm, dyn):
            assert np.array_equal(user.mass_matrix(q), m)
            assert np.array_equal(user.gravity(q), g)
        assert np.array_equal(dyn.rnea(q, qd, qdd), pin.rnea(ref, ref_data, q, qd, qdd))
        assert np.array_equal(dyn.aba(q, qd, tau), pin.aba(ref, ref_data, q, qd, tau))

    # the IK reference had Pinocchio's default gravity: its kinematics are the same
    old_tip = _independent(urdf, None)
    old_data = old_tip.createData()
    fid = old_tip.getFrameId(desc.tip_frame)
    p, z = tip.fk(poses)
    for k, q in enumerate(poses):
        pin.framesForwardKinematics(old_tip, old_data, q)
        assert np.array_equal(p[k], old_data.oMf[fid].translation)
        assert np.array_equal(z[k], old_data.oMf[fid].rotation[:, 2])
    assert tip.frame_id == fid
    assert np.array_equal(tip.lower, old_tip.lowerPositionLimit)
    assert np.array_equal(tip.upper, old_tip.upperPositionLimit)

    # the plant: semi-implicit Euler on ABA, as ModelPlant.step does
    plant = users["plant"]
    q, qd = poses[1].copy(), np.zeros(len(poses[1]))
    tau = rng.normal(size=len(q))
    plant.reset(q)
    plant.apply(tau)
    plant.step(25)
    for _ in range(25):
        qd += pin.aba(ref, ref_data, q, qd, tau) * plant.dt
        q += qd * plant.dt
    assert np.array_equal(plant.q, q)
    pin.forwardKinematics(ref, ref_data, q)
    f = pin.updateFramePlacement(ref, ref_data, ref.getFrameId(desc.tip_frame))
    pos, rot = plant.tip_pose()
    assert np.array_equal(pos, f.translation) and np.array_equal(rot, f.rotation)

    # the collision model on a model of its own, as it was built before
    monkeypatch.setattr(collision_model, "pinocchio_model",
                        lambda text, gravity: pin.buildModelFromXML(text))
    old_coll = CollisionModel(desc)
    assert old_coll.model is not shared
    coll = users["collision"]
    assert np.array_equal(coll.clearance(poses), old_coll.clearance(poses))
    for a, b in zip(coll.frames(poses), old_coll.frames(poses), strict=True):
        assert np.array_equal(a, b)
    assert np.array_equal(coll.motion_bound_m(poses[:-1], poses[1:]),
                          old_coll.motion_bound_m(poses[:-1], poses[1:]))

    # and none of it changed the shared model
    assert shared == _independent(urdf, desc.gravity)
