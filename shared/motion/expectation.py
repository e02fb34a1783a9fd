"""Where the arm should be, against where it is (thesis §4.2.3): the reported arm's offset from
the expected joint vector, and the tool point's path along a plan (the predicted path of
statements sent and not yet done)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.motion.interpreter import Plan
from shared.robots.jog import JogFrames, world_T_tcp


@dataclass(frozen=True)
class ArmOffset:
    """How far a reported arm is from the expected one: the largest joint difference (rad; inf
    when the joint vectors differ in size) and the tool points' distance (m)."""

    joint: float
    tool: float

    def beyond(self, joint_limit: float, tool_limit: float) -> bool:
        return self.joint > joint_limit or self.tool > tool_limit


def arm_offset(robot, frames: JogFrames, q_reported: np.ndarray, q_expected: np.ndarray) -> ArmOffset:
    """The offset of the arm at ``q_reported`` from the arm at ``q_expected``."""
    q_reported = np.asarray(q_reported, dtype=float)
    q_expected = np.asarray(q_expected, dtype=float)
    if q_reported.size != q_expected.size:
        return ArmOffset(float("inf"), float("inf"))
    joint = float(np.max(np.abs(q_reported - q_expected))) if q_reported.size else 0.0
    tool = float(np.linalg.norm(world_T_tcp(robot, q_reported, frames)[:3, 3] - world_T_tcp(robot, q_expected, frames)[:3, 3]))
    return ArmOffset(joint, tool)


def tool_path(plan: Plan, robot, frames: JogFrames, points: int) -> np.ndarray:
    """(points, 3) world positions of the tool point at evenly spaced times along ``plan``
    (one point, its start, when the plan takes no time)."""
    ts = np.linspace(0.0, plan.duration, max(int(points), 1)) if plan.duration > 0 else np.zeros(1)
    qs = plan.sample(ts).q
    return np.array([world_T_tcp(robot, q, frames)[:3, 3] for q in qs])
