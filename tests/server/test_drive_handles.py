"""The gizmo's drags in the session (issue 16, finding 7): a ring in a plane turns the tool about
the plane's normal in the chosen frame, and a joint's ring turns the joint."""

from __future__ import annotations

import math

import numpy as np
import pytest

from server.console import Session
from shared.language.statements import Frame
from shared.spatial import exp_so3, log_so3


def test_the_ring_of_rotate_in_the_xy_plane_turns_the_tool_about_the_frame_s_z(session: Session, clock) -> None:
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
