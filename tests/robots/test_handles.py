"""The drag handles a jog choice offers, where they stand, and what a drag of them asks
(issue 16, finding 7: handles that match the choices, drawn in the chosen frame, a ring on a
joint)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.robots.handles import (
    JOINT_HANDLES,
    handle_turn,
    joint_handle,
    tool_goal,
    tool_handle,
    tool_handles,
)
from shared.robots.jog import JogFrames, jog_tool, world_T_tcp
from shared.spatial import exp_so3, log_so3

CELL = load_cell(DEFAULT_CELL)
ROBOT = CELL.robot
FRAMES = JogFrames(CELL.world_T_base, CELL.frame("work"), CELL.flange_T_tcp)


def test_translating_along_an_axis_offers_only_that_arrow() -> None:
    z = tool_handles("z", "translate")
    assert (z.active_axes, z.arrows, z.planes, z.rings) == ((False, False, True), True, False, False)
    xy = tool_handles("xy", "translate")
    assert (xy.active_axes, xy.arrows, xy.planes, xy.rings) == ((True, True, False), True, True, False)


@pytest.mark.parametrize(("constraint", "ring_about"), [("z", 2), ("xy", 2), ("x", 0), ("yz", 0), ("xz", 1)])
def test_rotating_offers_the_one_ring_the_jog_turns_about(constraint: str, ring_about: int) -> None:
    choice = tool_handles(constraint, "rotate")
    # a gizmo ring about axis k shows when the two other axes are active
    assert [not a for a in choice.active_axes].count(True) == 1 and not choice.active_axes[ring_about]
    assert (choice.arrows, choice.planes, choice.rings) == (False, False, True)
    # and that ring moves the arm: a turn about it passes the constraint
    d = np.zeros(3)
    d[ring_about] = 0.05
    result = jog_tool(ROBOT, CELL.q_home, frames=FRAMES, frame="world", constraint=constraint, motion="rotate", displacement=d)
    assert result.moved
    turned = log_so3(world_T_tcp(ROBOT, result.q, FRAMES)[:3, :3] @ world_T_tcp(ROBOT, CELL.q_home, FRAMES)[:3, :3].T)
    np.testing.assert_allclose(turned, d, atol=1e-9)
    assert JOINT_HANDLES.rings and not JOINT_HANDLES.arrows


@pytest.mark.parametrize("frame", ["world", "base", "work", "tool"])
def test_the_tool_handle_has_the_frame_s_axes_and_a_turned_ring_turns_the_tool_alike(frame: str) -> None:
    now = world_T_tcp(ROBOT, CELL.q_home, FRAMES)
    handle = tool_handle(frame, FRAMES, now)
    expected = {"world": np.eye(3), "base": CELL.world_T_base[:3, :3], "work": CELL.frame("work")[:3, :3], "tool": now[:3, :3]}[frame]
    np.testing.assert_allclose(handle.world_T_handle[:3, :3], expected, atol=1e-12)
    np.testing.assert_allclose(handle.world_T_handle[:3, 3], now[:3, 3], atol=1e-12)
    np.testing.assert_allclose(tool_goal(handle.world_T_handle, handle.handle_T_tcp), now, atol=1e-12)
    # the ring about the handle's z turned by 10 deg: the tool turns 10 deg about the frame's z
    dragged = handle.world_T_handle.copy()
    dragged[:3, :3] = dragged[:3, :3] @ exp_so3(np.array([0.0, 0.0, math.radians(10.0)]))
    goal = tool_goal(dragged, handle.handle_T_tcp)
    np.testing.assert_allclose(log_so3(goal[:3, :3] @ now[:3, :3].T), expected[:, 2] * math.radians(10.0), atol=1e-12)
    np.testing.assert_allclose(goal[:3, 3], now[:3, 3], atol=1e-12)


@pytest.mark.parametrize("joint", range(1, 7))
def test_a_joint_handle_stands_on_the_joint_s_axis_and_its_turn_is_the_joint_s(joint: int) -> None:
    q = CELL.q_home.copy()
    h0 = joint_handle(ROBOT, q, joint, CELL.world_T_base)
    q[joint - 1] += 0.2
    h1 = joint_handle(ROBOT, q, joint, CELL.world_T_base)
    np.testing.assert_allclose(h1[:3, 3], h0[:3, 3], atol=1e-12)  # the joint turns about its own origin
    np.testing.assert_allclose(h1[:3, 2], h0[:3, 2], atol=1e-12)  # ... and axis
    assert handle_turn(h0, h1) == pytest.approx(0.2, abs=1e-12)
    # the axis is the joint's: the links beyond turn about it (the tool point moves on a circle about it)
    p0 = world_T_tcp(ROBOT, CELL.q_home, FRAMES)[:3, 3]
    p1 = world_T_tcp(ROBOT, q, FRAMES)[:3, 3]
    expected = h0[:3, 3] + exp_so3(h0[:3, 2] * 0.2) @ (p0 - h0[:3, 3])
    np.testing.assert_allclose(p1, expected, atol=1e-9)
