"""What leaves for the robot is exactly the program's lines (issue 16, finding 2 and "Regimes"):
a MODE statement a regime needs is put into the program as a line marked as the console's, the
submission is refused once, and the operator sees it, then sends it or deletes it; the robot's
mode is predicted from what was sent and ran; the operation regime takes the console's own
programs one step at a time. The session runs against the in-memory robot of
``test_console_dispatch`` (the ``RobotLink`` seam), in virtual time."""

# ruff: noqa: F811 - the imported fixtures are test parameters by the same name
from __future__ import annotations

import pytest
from test_console_dispatch import (  # noqa: F401 - fixtures used by name
    FakeRobot,
    cell_and_scene,
    robot,
    statuses,
    wait_until,
)

from server.console import FINAL_SENT, ConflictError, Regime, SentStatus, Session
from server.console.errors import ConsoleLineAdded
from server.robot_client import CommunicationRejected
from shared.cells.loader import load_cell
from shared.collision import SceneModel
from shared.language.formatter import format_statement
from shared.language.parser import parse_statement
from shared.paths import ASSETS_DIR
from shared.wire.messages import Rejected, RejectReason, StatementState

CONTACT_DRAW = "DRAW TO (0, -80, 75) mm IN WORK WITH SPEED 10 mm/s UNTIL CONTACT"


def lines(session: Session) -> list[str]:
    return [e.text for e in session.program.view().entries if e.kind != "EMPTY"]


def sent(robot: FakeRobot, count: int) -> list[str]:
    """The texts of the fake's ``count``-th communication, once it has it."""
    wait_until(lambda: len(robot.submitted) >= count, f"communication {count} at the robot")
    return [format_statement(s) for s in robot.submitted[count - 1]]


def run_all(session: Session, robot: FakeRobot) -> None:
    """The robot runs everything it has: each statement done, the arm where the program predicted."""
    wait_until(lambda: all(s.number is not None or s.status in FINAL_SENT for s in session.dispatch.view().items), "the numbers")
    q = session.program.start.q
    for item in session.dispatch.view().items:
        if item.status not in FINAL_SENT:
            robot.report(item.number, StatementState.DONE, q=q)
    assert session.dispatch.view().pending == 0


def test_release_after_mode_position_goes_alone(session: Session, robot: FakeRobot) -> None:
    """The operator's MODE POSITION, then TASK release(): no MODE FORCE is sent in front of it."""
    session.modes.set_regime_override(Regime.OPERATION)
    for text in ("MODE POSITION", "TASK release()"):
        session.program.insert(text)
    session.dispatch.submit(0, 1)
    assert sent(robot, 1) == ["MODE POSITION"]
    run_all(session, robot)
    session.dispatch.submit(0, 1)
    assert sent(robot, 2) == ["TASK release()"]
    assert [s.text for s in session.dispatch.view().items] == ["MODE POSITION", "TASK release()"]


def test_a_mode_the_regime_needs_is_a_line_before_it_is_sent(session: Session, robot: FakeRobot) -> None:
    session.modes.set_regime_override(Regime.OPERATION)
    session.program.insert(CONTACT_DRAW)
    with pytest.raises(ConsoleLineAdded, match=r"submit needs MODE FORCE first .*added as line 1, submit again"):
        session.dispatch.submit(0, 1)
    assert robot.submitted == []  # nothing left: the operator first sees the line
    view = session.program.view()
    assert lines(session) == ["MODE FORCE", CONTACT_DRAW]
    added = view.entries[0]
    assert added.added_by == "console" and "UNTIL runs in force mode" in added.added_reason
    assert view.entries[1].added_by is None
    session.dispatch.submit(0, 2)
    assert sent(robot, 1) == ["MODE FORCE", CONTACT_DRAW]  # exactly the lines shown
    assert [s.text for s in session.dispatch.view().items] == ["MODE FORCE", CONTACT_DRAW]
    assert session.dispatch.robot_mode.value == "FORCE"


def test_the_operator_may_delete_the_added_line(session: Session, robot: FakeRobot) -> None:
    session.modes.set_regime_override(Regime.FREE)
    session.program.insert("MODE FORCE")
    session.dispatch.submit(0, 1)  # the operator's own choice: the robot goes to force mode
    run_all(session, robot)
    session.program.insert("DRIVE J1 TO 10 deg")
    with pytest.raises(ConsoleLineAdded, match=r"MODE POSITION .*added as line 1"):
        session.dispatch.submit(0, 1)
    assert lines(session) == ["MODE POSITION", "DRIVE J1 TO 10 deg"]
    session.program.select(0)
    session.program.delete()
    session.dispatch.submit(0, 1)  # declined: it goes as the operator left it, in force mode
    assert sent(robot, 2) == ["DRIVE J1 TO 10 deg"]
    run_all(session, robot)
    # in the operation regime the mode is the regime's rule: a deleted line is refused, not re-added
    session.modes.set_regime_override(Regime.OPERATION)
    session.program.insert("DRIVE J1 TO 12 deg")
    with pytest.raises(ConsoleLineAdded, match="MODE POSITION"):
        session.dispatch.submit(0, 1)
    session.program.select(0)
    session.program.delete()
    with pytest.raises(ConflictError, match="the MODE POSITION line the console added was deleted"):
        session.dispatch.submit(0, 1)
    assert lines(session) == ["DRIVE J1 TO 12 deg"] and len(robot.submitted) == 2


def test_a_mode_that_never_ran_is_not_the_robots_mode(session: Session, robot: FakeRobot) -> None:
    session.modes.set_regime_override(Regime.FREE)
    session.program.insert("MODE FORCE")
    answer = Rejected(comm_id=1, reason=RejectReason.BUFFER_FULL, detail="room for 0 statements")
    robot.reject = CommunicationRejected(answer, statements=1)
    session.dispatch.submit(0, 1)
    wait_until(lambda: statuses(session) == [SentStatus.REJECTED], "the rejection")
    session.program.insert("DRIVE J1 TO 10 deg")
    session.dispatch.submit(0, 1)  # the robot never went to force mode: nothing to add
    assert sent(robot, 2) == ["DRIVE J1 TO 10 deg"]


def test_the_operation_regime_takes_generated_moves_one_step_at_a_time(session: Session, robot: FakeRobot) -> None:
    session.modes.set_regime_override(Regime.OPERATION)
    session.program.insert("DRIVE J1 TO 10 deg")  # what a slider drag generates: no UNTIL, a clear path
    session.program.insert("EVENT turned")
    session.dispatch.submit(0, 2)
    assert sent(robot, 1) == ["DRIVE J1 TO 10 deg", "EVENT turned"]
    run_all(session, robot)
    for text in ("DRIVE J1 TO 12 deg", "DRIVE J1 TO 14 deg"):
        session.program.insert(text)
    with pytest.raises(ConflictError, match=r"one motion per step.*submit statements 1\.\.1 first"):
        session.dispatch.submit(0, 2)
    session.program.load("DRAW TO (0, -80, -30) mm IN WORK\n", "into_the_plate.tp")
    with pytest.raises(ConflictError, match=r"the DRAW \(statement 1\) has no UNTIL and its path is not clear"):
        session.dispatch.submit(0, 1)


@pytest.fixture
def rover_session(clock):
    cell = load_cell(ASSETS_DIR / "cells" / "rover_terrain.toml")
    s = Session(cell, scene=SceneModel.from_cell(cell, exclude=("terrain",)), clock=clock, wall_clock=clock)
    yield s
    s.close()


def test_the_operation_regime_takes_the_rover_placement_program(rover_session: Session, loop, clock) -> None:
    session = rover_session
    fake = FakeRobot(clock, loop)
    session.attach_robot(fake, loop)
    try:
        placement = session.terrain.place_instrument(ground_xy=(0.70, 0.0))
        session.terrain.insert_placement()
        assert lines(session) == placement.program
        session.modes.set_regime_override(Regime.OPERATION)
        steps = []
        while session.program.view().empty_index:
            n = session.program.view().empty_index
            try:
                session.dispatch.submit(0, n)
            except ConflictError as exc:
                assert "one motion per step" in str(exc), exc
                last = int(str(exc).rsplit("statements 1..", 1)[1].split()[0])
                session.dispatch.submit(0, last)
            steps.append(sent(fake, len(steps) + 1))
            run_all(session, fake)
        assert [t for step in steps for t in step] == placement.program  # all of it, as written
        assert len(steps) == sum(parse_statement(t).kind == "MOVE" for t in placement.program)
    finally:
        fake.open_gates()


def _robot_in_force_mode(session: Session, robot: FakeRobot) -> None:
    session.modes.set_regime_override(Regime.FREE)
    session.program.insert("MODE FORCE")
    session.dispatch.submit(0, 1)
    run_all(session, robot)
    assert session.dispatch.robot_mode.value == "FORCE"


def test_an_added_line_keeps_the_quasi_confirmation(session: Session, robot: FakeRobot, clock) -> None:
    """A MODE line changes no path: the range previewed to its end stays confirmed with it."""
    _robot_in_force_mode(session, robot)
    session.modes.set_regime_override(Regime.QUASI)
    session.program.insert("DRIVE J1 TO 10 deg")
    preview = session.preview.begin(0, 1)
    session.preview.seek(preview.duration)
    session.preview.end()
    assert session.program.view().confirmed == (0, 1)
    with pytest.raises(ConsoleLineAdded, match="added as line 1"):
        session.dispatch.submit(0, 1)
    assert session.program.view().confirmed == (0, 2)
    session.dispatch.submit(0, 2)
    assert sent(robot, 2) == ["MODE POSITION", "DRIVE J1 TO 10 deg"]


def test_streaming_shows_the_added_line_and_sends_it_with_the_move(session: Session, robot: FakeRobot, clock) -> None:
    _robot_in_force_mode(session, robot)
    seen = []
    session.subscribe_events(lambda e: seen.append(e))
    session.program.set_auto_generate(True)
    for _ in range(4):
        session.arm.jog_joint(1, 0.02)
        clock.advance(0.02)
    session.arm.release()
    texts = sent(robot, 2)
    assert texts[0] == "MODE POSITION" and texts[1].startswith("DRIVE J1") and len(texts) == 2
    shown = [e for e in seen if e.type == "program" and any(x.added_by == "console" for x in e.program.entries)]
    assert shown and shown[0].program.entries[0].text == "MODE POSITION"  # a line of the program before it left
