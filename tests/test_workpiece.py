"""A workpiece (a limb) in the panel's place: every plant carries it, none collides with it,
and the arm moves exactly as without it (issue 33: the plants carry the surface)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tattotronix.config.params import compose_settings
from tattotronix.errors import TattotronixError
from tattotronix.plants import PlantSettings, Workpiece, make_plant
from tattotronix.plants.base import PidSpec
from tattotronix.robot.description import RobotDescription
from tattotronix.surface.setup import work_surface

N = 5


@pytest.fixture(scope="module")
def limb() -> Workpiece:
    """The forearm phantom, posed on the bench as the surface stage poses it."""
    s = work_surface(compose_settings(["surface.kind=forearm"]).surface)
    return Workpiece(s.vertices / 1000.0, s.faces)


def _settings(desc: RobotDescription, contacts: bool) -> PlantSettings:
    cfg = compose_settings([f"plant.contacts={str(contacts).lower()}"])
    return PlantSettings.from_settings(cfg.plant, desc.gravity, desc.tip_frame)


def _play(backend: str, desc: RobotDescription, models: tuple[Path, Path],
          settings: PlantSettings, workpiece: Workpiece | None) -> np.ndarray:
    """q after each of 300 steps under a torque that swings every joint about."""
    urdf, mjcf = models
    out = []
    with make_plant(backend, settings, urdf=urdf, mjcf=mjcf, joint_names=desc.joint_names,
                    lower=desc.lower, upper=desc.upper, workpiece=workpiece) as plant:
        plant.reset(np.array([0.0, 0.6, -0.9, 0.0, 0.5]))
        for k in range(300):
            plant.apply(0.4 * np.sin(np.arange(N) + k * 0.02))
            plant.step(1)
            out.append(np.array(plant.q, dtype=np.float64))
    return np.array(out)


@pytest.mark.parametrize("backend", ["mujoco", "pybullet"])
@pytest.mark.parametrize("contacts", [False, True])
def test_the_limb_changes_nothing_the_arm_does(desc: RobotDescription,
                                               models: tuple[Path, Path], limb: Workpiece,
                                               backend: str, contacts: bool) -> None:
    settings = _settings(desc, contacts)
    bare = _play(backend, desc, models, settings, None)
    with_limb = _play(backend, desc, models, settings, limb)
    np.testing.assert_array_equal(with_limb, bare)  # bit for bit: it is never touched


def test_mujoco_shows_the_limb_in_the_panels_place(desc: RobotDescription,
                                                    models: tuple[Path, Path],
                                                    limb: Workpiece) -> None:
    import mujoco

    from tattotronix.plants.mujoco_plant import WORKPIECE, MujocoPid, MujocoPlant

    _, mjcf = models
    settings = _settings(desc, True)
    plant = MujocoPlant(mjcf, settings, workpiece=limb)
    m = plant.model
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, i) for i in range(m.ngeom)]
    assert WORKPIECE in names and "panel" not in names
    g = names.index(WORKPIECE)
    assert m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0
    assert m.geom_bodyid[g] == 0  # the world's: it adds no mass to the arm
    # where the limb is: its mesh's box, placed, is the limb's box
    mujoco.mj_forward(m, plant.data)
    mesh = m.geom_dataid[g]
    a, n = m.mesh_vertadr[mesh], m.mesh_vertnum[mesh]
    local = m.mesh_vert[a:a + n]
    placed = plant.data.geom_xpos[g] + local @ plant.data.geom_xmat[g].reshape(3, 3).T
    np.testing.assert_allclose(placed.min(axis=0), limb.vertices_m.min(axis=0), atol=1e-6)
    np.testing.assert_allclose(placed.max(axis=0), limb.vertices_m.max(axis=0), atol=1e-6)
    # the engine's own PID loop builds the same scene
    spec = PidSpec(kp=np.full(N, 10.0), ki=np.zeros(N), kd=np.ones(N),
                   limit=np.full(N, 2.0), gravity=True)
    pid = plant.engine_pid(spec)
    assert isinstance(pid, MujocoPid)
    assert WORKPIECE in [mujoco.mj_id2name(pid.model, mujoco.mjtObj.mjOBJ_GEOM, i)
                         for i in range(pid.model.ngeom)]
    plant.close()


def test_pybullet_shows_the_limb(desc: RobotDescription, models: tuple[Path, Path],
                                 limb: Workpiece) -> None:
    from tattotronix.plants.pybullet_plant import PybulletPlant

    urdf, _ = models
    with PybulletPlant(urdf, _settings(desc, True), workpiece=limb) as plant:
        p, cid = plant._p, plant.client
        assert plant.workpiece_body is not None
        shapes = p.getVisualShapeData(plant.workpiece_body, physicsClientId=cid)
        assert len(shapes) == 1 and shapes[0][2] == p.GEOM_MESH
        assert p.getCollisionShapeData(plant.workpiece_body, -1, physicsClientId=cid) == ()


@pytest.mark.parametrize("vertices, faces", [
    (np.zeros((2, 3)), np.array([[0, 1, 1]])),  # too few vertices
    (np.zeros((3, 3)), np.array([[0, 1, 3]])),  # a face past the vertices
    (np.full((3, 3), np.nan), np.array([[0, 1, 2]])),  # not finite
    (np.zeros((3, 2)), np.array([[0, 1, 2]])),  # not 3-D
    (np.zeros((3, 3)), np.zeros((0, 3), int)),  # no face
])
def test_a_bad_workpiece_is_refused(vertices: np.ndarray, faces: np.ndarray) -> None:
    with pytest.raises(TattotronixError, match="workpiece needs"):
        Workpiece(vertices, faces)
