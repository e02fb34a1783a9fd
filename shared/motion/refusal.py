"""Why the planner refuses a statement: one typed reason and a one-line message."""

from __future__ import annotations

from enum import Enum

from shared.errors import KinematicsError


class RefusalReason(str, Enum):
    UNREACHABLE = "unreachable"  # a point of the path has no inverse-kinematics solution at all
    JOINT_LIMIT = "joint_limit"  # the target, or a point of the path, needs a joint outside its range
    JOINT_JUMP = "joint_jump"  # following the path would need a jump to another arm configuration
    UNSUPPORTED = "unsupported"  # the robot cannot do this kind of motion (e.g. orient a 3-DOF arm)
    INVALID = "invalid"  # the statement does not fit the robot (joint count, speed unit, ...)
    AFTER_TASK = "after_task"  # a statement after a task call, whose end state is not known here
    INTERFERENCE = "interference"  # the goal is inside a mechanical interference zone, or no detour exists


class PlanRefused(KinematicsError):
    """A statement the planner will not turn into a trajectory.

    ``reason`` says which rule refused it; ``index`` is the statement's 0-based place in the
    program when known; ``at`` is the path parameter in [0, 1] where a Cartesian path failed.
    """

    def __init__(self, reason: RefusalReason, message: str, *, index: int | None = None, at: float | None = None) -> None:
        self.reason = reason
        self.index = index
        self.at = at
        self.detail = message
        where = f"statement {index + 1}: " if index is not None else ""
        super().__init__(f"{where}{message} ({reason.value})")

    def at_index(self, index: int) -> "PlanRefused":
        """The same refusal, placed at statement ``index``."""
        return PlanRefused(self.reason, self.detail, index=index, at=self.at)
