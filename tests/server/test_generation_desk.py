"""Generation in the session writes what the operator meant (issue 16, finding 5): on from the
start, one statement per straight stroke (one undo takes it back), one DRIVE per slider drag,
targets in the frame the operator jogs in."""

from __future__ import annotations

import numpy as np

from server.console import Session
from shared.language.statements import Frame, Speed, SpeedUnit

TEXT_MM = 0.5e-4 + 1e-12  # m: generated targets carry 0.1 mm (shared.program.generator), half a step of rounding


def stroke(session: Session, clock, frame: str, axis: int, pieces: list[float], steps: int = 6, pause: int = 8) -> None:
    """Jog the tool along one axis of ``frame``: each piece (m) at a steady pace, with a pause
    (the arm held still while sampled) between pieces, then let go."""
    for piece in pieces:
        for _ in range(steps):
            d = np.zeros(3)
            d[axis] = piece / steps
            session.arm.jog_tool(frame=frame, constraint="xyz"[axis], motion="translate", displacement=d)
            clock.advance(0.02)
        for _ in range(pause):
            session.arm.jog_tool(frame=frame, constraint="xyz"[axis], motion="translate", displacement=np.zeros(3))
            clock.advance(0.02)
    session.arm.release()
    clock.advance(0.5)


def statements(session: Session) -> list:
    return [e.statement for e in session.program.view().entries if e.statement is not None]


def test_generation_is_on_from_the_start(session: Session, clock) -> None:
    assert session.program.view().auto_generate
    stroke(session, clock, "world", 0, [0.03])
    assert [s.kind for s in statements(session)] == ["DRAW"]


def test_a_straight_stroke_with_pauses_is_one_draw_and_one_undo(session: Session, clock) -> None:
    stroke(session, clock, "world", 0, [0.02, 0.015, 0.02])
    program = statements(session)
    assert [s.kind for s in program] == ["DRAW"], [str(s) for s in program]
    tcp = session.arm.view().world_T_tcp
    np.testing.assert_allclose(np.array(program[0].position) * 1e3, np.asarray(tcp)[:3, 3] * 1e3, atol=TEXT_MM * 1e3)
    session.program.undo()
    assert statements(session) == []  # the whole stroke was one edit


def test_each_segment_is_in_the_frame_the_operator_jogs_in(session: Session, clock) -> None:
    stroke(session, clock, "work", 2, [0.03])
    world_p_after_first = np.asarray(session.arm.view().world_T_tcp)[:3, 3]
    stroke(session, clock, "base", 0, [0.02])
    stroke(session, clock, "world", 1, [0.02])
    program = statements(session)
    assert [(s.kind, s.frame) for s in program] == [("DRAW", Frame.WORK), ("DRAW", Frame.BASE), ("DRAW", Frame.WORLD)]
    # each target is where its stroke ended, in its own frame's coordinates
    work_p = (np.linalg.inv(session.cell.frame("work")) @ np.append(world_p_after_first, 1.0))[:3]
    np.testing.assert_allclose(np.array(program[0].position), work_p, atol=TEXT_MM)
    np.testing.assert_allclose(np.array(program[-1].position), np.asarray(session.arm.view().world_T_tcp)[:3, 3], atol=TEXT_MM)


def test_a_slider_dragged_in_steps_is_one_drive(session: Session, clock) -> None:
    q6 = session.arm.state.q[5]
    for k in range(1, 8):  # a slider sends its value in steps, with pauses between them
        session.arm.set_joint(6, q6 + np.radians(2.0 * k))
        clock.advance(0.05)
        session.arm.set_joint(6, q6 + np.radians(2.0 * k))
        clock.advance(0.3)
        if k % 3 == 0:
            session.arm.release()  # the slider's "let go" (a pause) in the middle of the drag
    session.arm.release()
    program = statements(session)
    assert [(s.kind, s.joint) for s in program] == [("DRIVE", 6)]
    assert abs(program[0].target - (q6 + np.radians(14.0))) <= np.radians(0.05) + 1e-12  # the text's 0.1 deg


def test_a_statement_the_operator_changed_or_followed_is_not_merged_into(session: Session, clock) -> None:
    stroke(session, clock, "world", 0, [0.02])
    session.program.select(0)
    session.program.modify_conditions(speed=Speed(value=0.01, unit=SpeedUnit.M_PER_S))
    stroke(session, clock, "world", 0, [0.02])  # the same line on: the edited DRAW stays as it is
    assert [(s.kind, s.speed is not None) for s in statements(session)] == [("DRAW", True), ("DRAW", False)]
    session.program.select(session.program.view().empty_index)
    session.program.insert("DRIVE J1 TO 5 deg")  # a statement after the DRAW
    stroke(session, clock, "world", 0, [0.02])
    assert [s.kind for s in statements(session)] == ["DRAW", "DRAW", "DRIVE", "DRAW"]


def test_strokes_go_on_merging_while_the_operator_has_the_line_selected(session: Session, clock) -> None:
    stroke(session, clock, "world", 0, [0.015])
    session.program.select(0)  # the operator looks at the statement: a selection move, not an edit
    stroke(session, clock, "world", 0, [0.015])
    stroke(session, clock, "world", 0, [0.015])
    view = session.program.view()
    assert [e.kind for e in view.entries] == ["DRAW", "EMPTY"] and view.selected == 0
    np.testing.assert_allclose(np.array(view.entries[0].statement.position), np.asarray(session.arm.view().world_T_tcp)[:3, 3], atol=TEXT_MM)
