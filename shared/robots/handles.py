"""Drag handles for the virtual arm (thesis 4.3.4): which handles a jog choice allows, where the
handle stands, and what a drag of it asks of the arm.

* The tool's handle stands at the tool point with the axes of the chosen jog frame (world,
  base, work, or the tool's own), so its arrows point where the jog moves. Translating along
  one axis offers that axis's arrow; in a plane, the plane's two arrows and its square;
  rotating about an axis, or in a plane (about the plane's normal, ``shared.robots.jog``),
  offers the one ring about that axis.
* A drag moves the handle; the tool follows it with the grip it had when the handle was placed
  (``ToolHandle.handle_T_tcp``), so a turn of a frame-aligned ring turns the tool by the same
  rotation.
* A joint's handle stands at the joint's origin with its z axis along the joint's axis (the
  direction in which the joint turns positive): one ring, and a drag's turn about that z axis
  is the joint's change.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from shared.errors import InputError, UnknownNameError
from shared.robots.jog import (
    CONSTRAINTS,
    MOTIONS,
    JogFrames,
    frame_rotation,
    rotation_axis_mask,
)
from shared.robots.model import Robot
from shared.spatial import invert


@dataclass(frozen=True)
class HandleChoice:
    """Which parts of a transform gizmo to offer: the axes it may act along or about
    (``active_axes``, x y z of the handle's frame), and whether its arrows (translate along an
    axis), plane squares (translate in a plane) and rings (rotate about an axis) show."""

    active_axes: tuple[bool, bool, bool]
    arrows: bool
    planes: bool
    rings: bool


def tool_handles(constraint: str, motion: str) -> HandleChoice:
    """The handles a tool jog under ``constraint`` and ``motion`` allows. A gizmo ring about
    axis k needs the other two axes active, so a rotation offers exactly the ring about the
    axis it turns about."""
    if constraint not in CONSTRAINTS:
        raise UnknownNameError("direction constraint", constraint, CONSTRAINTS)
    if motion not in MOTIONS:
        raise UnknownNameError("motion", motion, MOTIONS)
    if motion == "translate":
        axes = tuple(c in constraint for c in "xyz")
        return HandleChoice(axes, arrows=True, planes=len(constraint) == 2, rings=False)  # type: ignore[arg-type]
    about = rotation_axis_mask(constraint)
    axes = tuple(not bool(a) for a in about)
    return HandleChoice(axes, arrows=False, planes=False, rings=True)  # type: ignore[arg-type]


JOINT_HANDLES = HandleChoice((True, True, False), arrows=False, planes=False, rings=True)
"""A joint's handle: the one ring about its z axis (the joint's axis)."""


@dataclass(frozen=True)
class ToolHandle:
    """The tool's handle: its pose (world) and the tool point's pose relative to it."""

    world_T_handle: np.ndarray
    handle_T_tcp: np.ndarray


def tool_handle(frame: str, frames: JogFrames, world_T_tcp: np.ndarray) -> ToolHandle:
    """The tool's handle for jogs in ``frame``: at the tool point, with the frame's axes."""
    world_T_handle = np.eye(4)
    world_T_handle[:3, :3] = frame_rotation(frame, frames, world_T_tcp)
    world_T_handle[:3, 3] = world_T_tcp[:3, 3]
    return ToolHandle(world_T_handle, invert(world_T_handle) @ world_T_tcp)


def tool_goal(world_T_handle: np.ndarray, handle_T_tcp: np.ndarray) -> np.ndarray:
    """Where a dragged handle asks the tool point to be (world)."""
    return _pose(world_T_handle, "handle pose") @ _pose(handle_T_tcp, "grip")


FINE_FAR_M = 0.10
"""Clearance (m) from the tool to the nearest object or the ground at and beyond which a drag moves
the tool as far as the handle."""
FINE_NEAR_M = 0.01
"""Clearance at and below which a drag moves the tool ``FINE_GAIN`` of the handle's motion."""
FINE_GAIN = 0.25


def fine_gain(clearance_m: float | None) -> float:
    """How much of a handle's motion the tool follows at ``clearance_m`` from the nearest object
    or the ground (None: nothing near): 1 far off, falling linearly to ``FINE_GAIN`` near contact,
    so the last centimetres take four times the hand's travel."""
    if clearance_m is None or not np.isfinite(clearance_m) or clearance_m >= FINE_FAR_M:
        return 1.0
    t = (max(clearance_m, FINE_NEAR_M) - FINE_NEAR_M) / (FINE_FAR_M - FINE_NEAR_M)
    return float(FINE_GAIN + (1.0 - FINE_GAIN) * t)


def scaled_step(world_T_goal: np.ndarray, world_T_was: np.ndarray, world_T_now: np.ndarray, gain: float) -> np.ndarray:
    """``world_T_goal`` moved by ``gain`` times the handle's step from ``world_T_was`` to
    ``world_T_now``: the translation scaled, the turn (about the goal's own point, in world
    axes) scaled in angle. Accumulated step by step over a drag, a gain that changes as the tool
    nears something never throws the goal back."""
    goal, was, now = _pose(world_T_goal, "goal"), _pose(world_T_was, "handle pose"), _pose(world_T_now, "handle pose")
    out = goal.copy()
    out[:3, 3] = goal[:3, 3] + gain * (now[:3, 3] - was[:3, 3])
    turn = pin.log3(now[:3, :3] @ was[:3, :3].T)
    out[:3, :3] = pin.exp3(gain * turn) @ goal[:3, :3]
    return out


def joint_handle(robot: Robot, q: np.ndarray, joint: int, world_T_base: np.ndarray) -> np.ndarray:
    """``world_T_handle`` of joint ``joint`` (1-based) at ``q``: at the joint's origin, z along
    the axis about which the joint turns positive."""
    q = robot.as_q(q)
    if not 1 <= joint <= robot.dof:
        raise InputError(f"joint J{joint} does not exist; {robot.name!r} has J1..J{robot.dof}")
    model = robot.model
    data = robot.new_data()
    pin.forwardKinematics(model, data, q)
    joint_id = joint  # joints are added in order after the universe (pinocchio id 0)
    local_axis = np.asarray(data.joints[joint_id].S).reshape(6, -1)[3:6, 0]
    norm = float(np.linalg.norm(local_axis))
    if norm < 1e-12:
        raise InputError(f"joint J{joint} of {robot.name!r} is not a revolute joint: no ring to turn it")
    z = local_axis / norm
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    align = np.eye(4)
    align[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return world_T_base @ data.oMi[joint_id].homogeneous @ align


def handle_turn(world_T_handle_now: np.ndarray, world_T_handle_goal: np.ndarray) -> float:
    """The turn (rad) about the handle's own z axis from where it stands to where it is
    dragged; whatever the drag did about other axes is not a turn of the joint."""
    r = _pose(world_T_handle_now, "handle pose")[:3, :3].T @ _pose(world_T_handle_goal, "handle goal")[:3, :3]
    return float(np.arctan2(r[1, 0] - r[0, 1], r[0, 0] + r[1, 1]))


def _pose(value: np.ndarray, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (4, 4) or not np.all(np.isfinite(arr)):
        raise InputError(f"{what} must be a finite 4x4 transform, got shape {arr.shape}")
    return arr
