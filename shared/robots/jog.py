"""Jogging the virtual robot as thesis section 4.3.4 specifies.

Four choices combine: the moving part (a joint, or the tool), the frame (world, base, work,
tool), the direction constraint (one axis or one plane) and the kind of motion (translate or
rotate). Rules: a joint only turns about its own z axis; the tool may move in any frame, along
any axis or plane, translating or rotating. Rotating about an axis turns about that axis;
rotating in a plane turns within it, about the plane's normal (the xy plane: about z), which is
the one ring a gizmo shows for that plane. Joint limits and singularities stop the motion
with a reason; the arm never jumps to another configuration.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from shared.errors import InputError, UnknownNameError
from shared.robots.ik import ik_target, positions_tool_only
from shared.robots.ik_kernels import solve_ik_nearest
from shared.robots.model import Robot
from shared.spatial import exp_so3, invert, log_so3

FrameName = Literal["world", "base", "work", "tool"]
Constraint = Literal["x", "y", "z", "xy", "yz", "xz"]
Motion = Literal["translate", "rotate"]
BlockReason = Literal["joint_limit", "singularity", "unreachable"]

FRAME_NAMES: tuple[str, ...] = get_args(FrameName)
CONSTRAINTS: tuple[str, ...] = get_args(Constraint)
MOTIONS: tuple[str, ...] = get_args(Motion)

#: largest joint change (rad) accepted for one jog step; more means the IK branch would jump
MAX_STEP_JOINT_CHANGE = np.radians(20.0)
#: smallest singular value of the tool Jacobian's scaled form below which the arm is singular
SINGULAR_VALUE_LIMIT = 1e-3


@dataclass(frozen=True)
class JogFrames:
    """Where the named frames are: ``world_T_base``, ``world_T_work`` and the tool point
    ``tool_T_tcp`` (the cell's gripper centre relative to the robot's tool point)."""

    world_T_base: np.ndarray
    world_T_work: np.ndarray
    tool_T_tcp: np.ndarray

    @classmethod
    def identity(cls) -> "JogFrames":
        return cls(np.eye(4), np.eye(4), np.eye(4))


@dataclass(frozen=True)
class JogResult:
    """Outcome of one jog step: the new joint vector (unchanged if blocked) and why not."""

    q: np.ndarray
    moved: bool
    blocked: BlockReason | None = None
    message: str = ""


def _axis_mask(constraint: str) -> np.ndarray:
    if constraint not in CONSTRAINTS:
        raise UnknownNameError("direction constraint", constraint, CONSTRAINTS)
    return np.array([c in constraint for c in "xyz"], dtype=float)


def rotation_axis_mask(constraint: str) -> np.ndarray:
    """The axes a rotation under ``constraint`` may turn about: the axis itself, or a plane's
    normal (a turn within the plane)."""
    mask = _axis_mask(constraint)
    return mask if len(constraint) == 1 else 1.0 - mask


def world_T_tcp(robot: Robot, q: np.ndarray, frames: JogFrames) -> np.ndarray:
    return frames.world_T_base @ robot.fk(q) @ frames.tool_T_tcp


def frame_rotation(name: str, frames: JogFrames, world_T_tcp_now: np.ndarray) -> np.ndarray:
    """World rotation of a named jog frame's axes."""
    if name == "world":
        return np.eye(3)
    if name == "base":
        return frames.world_T_base[:3, :3]
    if name == "work":
        return frames.world_T_work[:3, :3]
    if name == "tool":
        return world_T_tcp_now[:3, :3]
    raise UnknownNameError("frame", name, FRAME_NAMES)


def jog_joint(robot: Robot, q: np.ndarray, joint: int, delta: float) -> JogResult:
    """Turn joint ``joint`` (1-based) about its own z axis by ``delta`` rad; stop at its limit."""
    q = robot.as_q(q)
    if not 1 <= joint <= robot.dof:
        raise InputError(f"joint J{joint} does not exist; {robot.name!r} has J1..J{robot.dof}")
    i = joint - 1
    target = q[i] + float(delta)
    out = q.copy()
    if target > robot.upper[i] or target < robot.lower[i]:
        limit = robot.upper[i] if target > robot.upper[i] else robot.lower[i]
        out[i] = limit
        return JogResult(
            out, moved=bool(out[i] != q[i]), blocked="joint_limit",
            message=f"J{joint} stopped at its limit {np.degrees(limit):.1f} deg",
        )
    out[i] = target
    return JogResult(out, moved=delta != 0.0)


def _solve_step(robot: Robot, q: np.ndarray, world_T_tcp_target: np.ndarray, frames: JogFrames) -> JogResult:
    base_T_tool = invert(frames.world_T_base) @ world_T_tcp_target @ invert(frames.tool_T_tcp)
    position_only = positions_tool_only(robot)
    # only the solution nearest the current joints matters (the arm never jumps branch)
    target = ik_target(robot, base_T_tool)
    best = solve_ik_nearest(robot, q_seed=q, **target)
    if best is None:
        if solve_ik_nearest(robot, q_seed=q, respect_limits=False, **target) is not None:
            return JogResult(q, moved=False, blocked="joint_limit", message="the target needs a joint beyond its limit")
        return JogResult(q, moved=False, blocked="unreachable", message="the target is out of the arm's reach")
    change = np.abs(best - q)
    k = int(np.argmax(change))
    if change[k] > MAX_STEP_JOINT_CHANGE:
        return JogResult(
            q, moved=False, blocked="singularity",
            message=f"near a singularity: J{k + 1} would jump {np.degrees(change[k]):.0f} deg",
        )
    if not position_only:
        sigma = np.linalg.svd(robot.jacobian(best), compute_uv=False)
        if sigma[-1] < SINGULAR_VALUE_LIMIT:
            return JogResult(q, moved=False, blocked="singularity", message="the arm is at a singular configuration")
    return JogResult(best, moved=True)


def jog_tool(
    robot: Robot,
    q: np.ndarray,
    *,
    frames: JogFrames,
    frame: str,
    constraint: str,
    motion: str,
    displacement: np.ndarray,
) -> JogResult:
    """Move the tool point by ``displacement`` given in ``frame``'s axes: metres for
    ``translate``, a rotation vector (rad) about the tool point for ``rotate``. Components
    outside the constraint's axis or plane are dropped (for ``rotate``: all but the axis, or the
    plane's normal)."""
    q = robot.as_q(q)
    if motion not in MOTIONS:
        raise UnknownNameError("motion", motion, MOTIONS)
    mask = _axis_mask(constraint) if motion == "translate" else rotation_axis_mask(constraint)
    now = world_T_tcp(robot, q, frames)
    world_R_frame = frame_rotation(frame, frames, now)
    d_world = world_R_frame @ (mask * np.asarray(displacement, dtype=float))
    target = now.copy()
    if motion == "translate":
        target[:3, 3] += d_world
    else:
        if positions_tool_only(robot):
            return JogResult(q, moved=False, blocked="unreachable", message=f"{robot.name!r} controls the tool position only")
        target[:3, :3] = exp_so3(d_world) @ now[:3, :3]
    if not np.any(d_world):
        return JogResult(q, moved=False)
    return _solve_step(robot, q, target, frames)


def jog_tool_to(
    robot: Robot,
    q: np.ndarray,
    world_T_tcp_goal: np.ndarray,
    *,
    frames: JogFrames,
    frame: str,
    constraint: str,
    motion: str,
) -> JogResult:
    """Follow a dragged goal pose (the gizmo) as far as the constraint allows: the part of the
    goal's displacement along the constraint's axis or plane in ``frame``."""
    q = robot.as_q(q)
    now = world_T_tcp(robot, q, frames)
    world_R_frame = frame_rotation(frame, frames, now)
    if motion == "translate":
        d_frame = world_R_frame.T @ (world_T_tcp_goal[:3, 3] - now[:3, 3])
    else:
        d_frame = world_R_frame.T @ log_so3(world_T_tcp_goal[:3, :3] @ now[:3, :3].T)
    return jog_tool(robot, q, frames=frames, frame=frame, constraint=constraint, motion=motion, displacement=d_frame)
