"""Velocity and acceleration limits the planner keeps every trajectory within.

The robot files carry kinematics and joint ranges but no dynamics, so the limits live here:
defaults per robot (a PUMA 560-class arm, a small rover arm, and a cautious fallback for any
other robot), which a caller may replace with its own ``MotionLimits``. Every statement's speed
(``SPEED``, ``WITH SPEED``) is a fraction of, or an absolute value capped by, these maxima.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.errors import InputError
from shared.robots.model import Robot


@dataclass(frozen=True)
class MotionLimits:
    """Maxima of one robot (SI).

    ``joint_velocity`` (rad/s) and ``joint_acceleration`` (rad/s^2) are per joint, ``(dof,)``;
    ``linear_speed`` (m/s) and ``linear_acceleration`` (m/s^2) bound the tool point on straight
    lines; ``angular_speed`` (rad/s) and ``angular_acceleration`` (rad/s^2) bound the tool's
    rotation on Cartesian statements.
    """

    joint_velocity: np.ndarray
    joint_acceleration: np.ndarray
    linear_speed: float = 0.5
    linear_acceleration: float = 1.0
    angular_speed: float = 1.5
    angular_acceleration: float = 3.0

    def __post_init__(self) -> None:
        jv = np.asarray(self.joint_velocity, dtype=float).reshape(-1)
        ja = np.asarray(self.joint_acceleration, dtype=float).reshape(-1)
        if jv.shape != ja.shape:
            raise InputError(f"motion limits: {jv.size} joint velocities but {ja.size} joint accelerations")
        scalars = (self.linear_speed, self.linear_acceleration, self.angular_speed, self.angular_acceleration)
        if not (np.all(np.isfinite(jv)) and np.all(jv > 0) and np.all(np.isfinite(ja)) and np.all(ja > 0)):
            raise InputError("motion limits: joint velocities and accelerations must be finite and positive")
        if not all(np.isfinite(v) and v > 0 for v in scalars):
            raise InputError("motion limits: Cartesian speeds and accelerations must be finite and positive")
        jv.setflags(write=False)
        ja.setflags(write=False)
        object.__setattr__(self, "joint_velocity", jv)
        object.__setattr__(self, "joint_acceleration", ja)

    @property
    def dof(self) -> int:
        return int(self.joint_velocity.size)

    def check_robot(self, robot: Robot) -> None:
        if self.dof != robot.dof:
            raise InputError(f"motion limits are for {self.dof} joints but robot {robot.name!r} has {robot.dof}")


# PUMA 560-class arm: rated tool speed about 0.5 m/s; the three big joints turn at up to about
# 1.5 rad/s and the wrist at about 3 rad/s. Accelerations are conservative (two to three times
# the velocity per second) so that the simulated servo can always follow.
PUMA_LIMITS = MotionLimits(
    joint_velocity=np.array([1.5, 1.5, 1.5, 3.0, 3.0, 3.0]),
    joint_acceleration=np.array([3.0, 3.0, 3.0, 6.0, 6.0, 6.0]),
    linear_speed=0.5,
    linear_acceleration=1.0,
    angular_speed=1.5,
    angular_acceleration=3.0,
)


def default_limits(robot: Robot) -> MotionLimits:
    """The limits the planner uses for ``robot`` unless told otherwise."""
    if robot.description.ik == "puma" and robot.dof == 6:
        return PUMA_LIMITS
    if robot.description.ik == "rover":
        # a light instrument arm: slow, gentle
        return MotionLimits(
            joint_velocity=np.full(robot.dof, 0.5),
            joint_acceleration=np.full(robot.dof, 1.0),
            linear_speed=0.1,
            linear_acceleration=0.2,
            angular_speed=0.5,
            angular_acceleration=1.0,
        )
    return MotionLimits(joint_velocity=np.full(robot.dof, 1.0), joint_acceleration=np.full(robot.dof, 2.0))
