"""The gizmo's drags in the session (issue 16, finding 7): a ring in a plane turns the tool about
the plane's normal in the chosen frame, and a joint's ring turns the joint."""

from __future__ import annotations

import math

import numpy as np
import pytest

from server.console import Session
from shared.language.statements import Frame
from shared.robots.handles import FINE_FAR_M, FINE_GAIN, fine_gain
from shared.spatial import exp_so3, log_so3


def _clear_of_everything(session: Session) -> None:
    """Lift the tool until nothing is within ``FINE_FAR_M``: a drag there moves it as far as the handle."""
    while (d := session.arm.collision_view().min_distance) is not None and d < FINE_FAR_M + 0.03:  # with room to turn
        session.arm.jog_tool(frame="world", constraint="z", motion="translate", displacement=np.array([0.0, 0.0, 0.01]))
    session.arm.release()
    session.program.load("", "empty.tp")


def test_the_ring_of_rotate_in_the_xy_plane_turns_the_tool_about_the_frame_s_z(session: Session, clock) -> None:
    _clear_of_everything(session)
    start = np.asarray(session.arm.view().world_T_tcp)
    handle = session.arm.tool_handle("work")
    for k in range(1, 6):
        dragged = handle.world_T_handle.copy()
        dragged[:3, :3] = dragged[:3, :3] @ exp_so3(np.array([0.0, 0.0, math.radians(2.0 * k)]))
        session.arm.drag_tool_handle(dragged, handle.handle_T_tcp, frame="work", constraint="xy", motion="rotate")
        clock.advance(0.03)
    session.arm.release()
    now = np.asarray(session.arm.view().world_T_tcp)
    work_z = session.cell.frame("work")[:3, 2]
    np.testing.assert_allclose(log_so3(now[:3, :3] @ start[:3, :3].T), work_z * math.radians(10.0), atol=1e-6)
    np.testing.assert_allclose(now[:3, 3], start[:3, 3], atol=1e-6)
    program = [e.statement for e in session.program.view().entries if e.statement is not None]
    assert [(s.kind, s.frame) for s in program] == [("ROTATE", Frame.WORK)]


def test_a_joint_s_ring_turns_that_joint(session: Session, clock) -> None:
    q0 = session.arm.state.q.copy()
    start = session.arm.joint_handle(3)
    for k in range(1, 5):
        dragged = start.copy()
        dragged[:3, :3] = dragged[:3, :3] @ exp_so3(np.array([0.0, 0.0, math.radians(-3.0 * k)]))
        session.arm.turn_joint_to_handle(3, dragged)
        clock.advance(0.03)
    session.arm.release()
    q = session.arm.state.q
    assert q[2] == pytest.approx(q0[2] - math.radians(12.0), abs=1e-9)
    np.testing.assert_allclose(np.delete(q, 2), np.delete(q0, 2), atol=1e-12)
    program = [e.statement for e in session.program.view().entries if e.statement is not None]
    assert [(s.kind, s.joint) for s in program] == [("DRIVE", 3)]


def test_near_an_object_a_drag_moves_the_tool_a_fraction_of_the_handle(session: Session, clock) -> None:
    """Finer near objects (issue 37): 65 mm over the peg the tool follows ``fine_gain`` of each of
    the handle's steps, step by step as the clearance shrinks; clear of everything, all of it."""
    assert fine_gain(None) == fine_gain(FINE_FAR_M) == 1.0 and fine_gain(0.0) == FINE_GAIN
    near = session.arm.collision_view().min_distance
    assert near is not None and near < FINE_FAR_M
    start = np.asarray(session.arm.view().world_T_tcp)[:3, 3].copy()
    handle = session.arm.tool_handle("world")
    expected = 0.0
    for k in range(1, 6):  # 5 steps of 4 mm down, towards the peg
        dragged = handle.world_T_handle.copy()
        dragged[2, 3] -= 0.004 * k
        expected += 0.004 * fine_gain(session.arm.collision_view().min_distance)
        session.arm.drag_tool_handle(dragged, handle.handle_T_tcp, frame="world", constraint="z", motion="translate")
        clock.advance(0.03)
    session.arm.release()
    moved = start[2] - np.asarray(session.arm.view().world_T_tcp)[2, 3]
    assert moved == pytest.approx(expected, abs=1e-6) and moved < 0.020 * 0.9  # less than the handle's 20 mm
    _clear_of_everything(session)
    start = np.asarray(session.arm.view().world_T_tcp)[:3, 3].copy()
    handle = session.arm.tool_handle("world")
    dragged = handle.world_T_handle.copy()
    dragged[0, 3] += 0.02
    session.arm.drag_tool_handle(dragged, handle.handle_T_tcp, frame="world", constraint="x", motion="translate")
    session.arm.release()
    np.testing.assert_allclose(np.asarray(session.arm.view().world_T_tcp)[:3, 3] - start, [0.02, 0.0, 0.0], atol=1e-6)
