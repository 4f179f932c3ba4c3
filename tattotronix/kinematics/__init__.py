"""Kinematics: a batched FK/Jacobian model of the chain and the whole-path IK."""

from __future__ import annotations

from tattotronix.kinematics.chain import Chain, ChainState
from tattotronix.kinematics.ik import (
    Conditioning,
    IkFailure,
    IkOptions,
    IkResult,
    IkVerificationError,
    PinocchioTip,
    PointResult,
    Verification,
    conditioning,
    ik_options,
    solve_path,
    solve_path_sequential,
    solve_point,
    task_jacobian,
    verify,
)

__all__ = [
    "Chain",
    "ChainState",
    "Conditioning",
    "IkFailure",
    "IkOptions",
    "ik_options",
    "IkResult",
    "IkVerificationError",
    "PinocchioTip",
    "PointResult",
    "Verification",
    "conditioning",
    "solve_path",
    "solve_path_sequential",
    "solve_point",
    "task_jacobian",
    "verify",
]
