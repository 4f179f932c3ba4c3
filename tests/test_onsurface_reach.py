"""Where the arm can tattoo on the forearm phantom (issue 33): the reachability map."""

from __future__ import annotations

import numpy as np
import pytest

from tattotronix.config.params import compose_settings
from tattotronix.errors import TattotronixError
from tattotronix.kinematics import Chain, ik_options
from tattotronix.kinematics.onsurface import cone_reach
from tattotronix.robot.description import build_description
from tattotronix.surface.cone import EllipticCone


def _under_the_arm(x_mm: float) -> EllipticCone:
    """The phantom lying across the arm's reach: its axis along the arm frame's y at
    ``x_mm`` from the base, its elbow end at y = -110 mm, its underside on the bench."""
    pose = np.eye(4)
    pose[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # limb x -> arm y, limb y -> arm -x
    pose[:3, 3] = [x_mm, -110.0, 30.0]
    return EllipticCone(220.0, 80.0, 55.0, 0.75, pose)


def test_the_top_of_the_limb_is_reached_along_the_normal_and_its_underside_is_not() -> None:
    cfg = compose_settings()
    chain = Chain.from_description(build_description(cfg.robot))
    reach = cone_reach(chain, _under_the_arm(170.0), 1.5, ik_options(cfg.ik),
                       list(cfg.ik.seed), n_along=8, n_around=16)
    top = (reach.around_deg >= 45) & (reach.around_deg <= 135)
    under = (reach.around_deg >= 225) & (reach.around_deg <= 315)
    assert reach.reachable[:, top].mean() >= 0.8
    assert not reach.reachable[:, under].any()  # the needle would point up, into the arm
    ok = reach.reachable
    assert np.nanmax(reach.tilt_deg) <= 1.0 and np.isnan(reach.tilt_deg[~ok]).all()
    assert np.isfinite(reach.cond[ok]).all()
    s = reach.summary()
    assert s["points"] == 128 and 0 < s["reachable_pct"] < 100
    assert s["steepest_reached_deg"] >= 40.0  # a needle tilted well off vertical


def test_a_grid_too_small_is_refused() -> None:
    cfg = compose_settings()
    chain = Chain.from_description(build_description(cfg.robot))
    with pytest.raises(TattotronixError, match="at least 2 x 4"):
        cone_reach(chain, _under_the_arm(170.0), 1.5, ik_options(cfg.ik), list(cfg.ik.seed),
                   n_along=1)
