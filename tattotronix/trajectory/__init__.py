"""Trajectory: a time law along the IK path within the joint limits, and its npz export.

* :mod:`~tattotronix.trajectory.path`: the joint-space path, densified travel, path
  derivatives.
* :mod:`~tattotronix.trajectory.timelaw`: the discrete time-optimal law (velocity and
  acceleration limits, continuous velocity).
* :mod:`~tattotronix.trajectory.travel`: planned travel (time-optimal joint-space moves
  between strokes, from home and home again), checked for collision and clearance.
* :mod:`~tattotronix.trajectory.plan`: feeds, the speed check and refusal, the
  :class:`Trajectory`, its metrics and ``data/trajectories/<name>.npz``.
"""

from __future__ import annotations

from tattotronix.trajectory.path import (
    APPROACH,
    MARK,
    TRAVEL,
    JointPath,
    corner_points,
    densify,
    path_derivatives,
    segment_kinds,
    turn_radii,
)
from tattotronix.trajectory.plan import (
    NPZ_KEYS,
    MoveSummary,
    SpeedLimit,
    SpeedRefused,
    Trajectory,
    TrajectoryParams,
    plan_trajectory,
    speed_limit,
)
from tattotronix.trajectory.timelaw import JointLimits, TimeLaw, time_parameterise
from tattotronix.trajectory.travel import (
    JointMove,
    MoveSamples,
    TravelPlanner,
    joint_move,
    way_home,
)

__all__ = [
    "APPROACH",
    "MARK",
    "NPZ_KEYS",
    "TRAVEL",
    "JointLimits",
    "JointMove",
    "JointPath",
    "MoveSamples",
    "MoveSummary",
    "SpeedLimit",
    "SpeedRefused",
    "TimeLaw",
    "Trajectory",
    "TrajectoryParams",
    "TravelPlanner",
    "corner_points",
    "densify",
    "joint_move",
    "path_derivatives",
    "plan_trajectory",
    "segment_kinds",
    "speed_limit",
    "time_parameterise",
    "turn_radii",
    "way_home",
]
