"""Regimes that explain themselves (issue 16, finding 6), on the session in virtual time: what
Submit needs is said before the click and always agrees with what Submit then does, it is
republished when it changes, and "Preview and submit" previews a range at the preview speed and
sends it when the preview ends without warnings (at once for "instant"), never when it warns.

The robot is a small fake on a real asyncio loop in a thread (the ``RobotLink`` seam): it
numbers what it is sent and records it."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterable

import pytest

from server.console import ConflictError, Notice, ReadinessChanged, Regime, Session
from server.robot_client import ChannelHealth
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel
from shared.errors import InputError
from shared.language.statements import Statement
from shared.wire.messages import RecoveryAck

WAIT_S = 10.0


def wait_until(condition, what: str) -> None:
    deadline = time.monotonic() + WAIT_S
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting until {what}")
        time.sleep(0.002)


class NumberingRobot:
    """Numbers every submission from 1 and keeps it; nothing else happens."""

    url = "fake://robot"
    reconnects = 0

    def __init__(self) -> None:
        self.connected = threading.Event()
        self.connected.set()
        self.submitted: list[list[Statement]] = []
        self._next = 1

    def health(self) -> ChannelHealth:
        return ChannelHealth(connected=True, command="live", heard_ago_s=0.1, silence_limit_s=1.5, telemetry="none",
                             telemetry_ago_s=None, halted=None, errors=0, last_error=None, refused=None,
                             buffer_full=None, session_id="robot-s1", restarts=0)

    def on_report(self, listener) -> None: ...

    def on_telemetry(self, listener, gate=None) -> None: ...

    def on_restart(self, listener) -> None: ...

    def on_account(self, listener) -> None: ...

    async def submit(self, statements: Iterable[Statement], timeout: float | None = None) -> tuple[int, ...]:
        statements = list(statements)
        self.submitted.append(statements)
        first, self._next = self._next, self._next + len(statements)
        return tuple(range(first, self._next))

    async def _ack(self) -> RecoveryAck:
        return RecoveryAck(command_id=1, applied=True)

    async def stop(self, timeout: float | None = None) -> RecoveryAck:
        return await self._ack()

    async def resume(self, timeout: float | None = None) -> RecoveryAck:
        return await self._ack()

    async def skip(self, number: int, timeout: float | None = None) -> RecoveryAck:
        return await self._ack()

    async def abort(self, timeout: float | None = None) -> RecoveryAck:
        return await self._ack()


@pytest.fixture(scope="module")
def cell_and_scene():
    """A coarser collision hierarchy than the conftest's: built faster, the same answers."""
    cell = load_cell(DEFAULT_CELL)
    return cell, SceneModel.from_cell(cell, leaf_size=8)


@pytest.fixture
def robot(session: Session, loop) -> NumberingRobot:
    fake = NumberingRobot()
    session.attach_robot(fake, loop)
    return fake


def program(session: Session, *lines: str) -> None:
    for line in lines:
        session.program.insert(line)


def refusal_of_submit(session: Session, start: int, stop: int) -> str | None:
    """What Submit does: None when it sent, else the sentence it refused with."""
    try:
        session.dispatch.submit(start, stop)
    except ConflictError as exc:
        refusal = getattr(exc, "refusal", None)
        return refusal.message if refusal is not None else str(exc)
    return None


def test_what_submit_needs_is_said_before_the_click_and_agrees_with_submit(session: Session, robot) -> None:
    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRIVE J1 TO 10 deg", "DRIVE J2 TO -50 deg")
    need = session.readiness.view()
    assert not need.ready and (need.start, need.stop) == (0, 2)
    assert need.line == ("OFFLINE: statements 1-2 must be previewed to their end without warnings "
                         "(not yet previewed; Preview and submit previews 1-2 and sends it)")
    assert need.blocker == refusal_of_submit(session, 0, 2)  # the page's words are the refusal's
    session.preview.begin(0, 1)
    assert "being previewed: end the preview first" in session.readiness.view().line
    assert session.readiness.view().blocker == refusal_of_submit(session, 0, 2)
    session.preview.step(1)
    session.preview.end()
    need = session.readiness.view()
    assert not need.ready and "(only 1 previewed;" in need.line and need.confirmed == (0, 1)
    assert need.blocker == refusal_of_submit(session, 0, 2)
    one = session.readiness.view(0, 1)
    assert one.ready and one.line.startswith("Ready to send 1 (OFFLINE")
    session.preview.begin(0, 2)
    session.preview.step(2)
    session.preview.end()
    need = session.readiness.view()
    assert need.ready and need.blocker is None and need.line.startswith("Ready to send 1-2")
    assert refusal_of_submit(session, 0, 2) is None  # and it went (on the robot client's loop)
    wait_until(lambda: len(robot.submitted) == 1, "the submission on the robot's loop")

    session.modes.set_regime_override(Regime.OPERATION)
    program(session, "DRIVE J1 TO 20 deg")
    waiting = session.readiness.view()  # the two sent are not final yet
    assert waiting.line.startswith("SINGLE STEP: one motion at a time, ended by its UNTIL condition or on a clear path;")
    assert not waiting.ready and waiting.state == "waiting until the previous statement is final"
    assert waiting.blocker == refusal_of_submit(session, 0, 1)


def test_single_step_says_one_statement_with_its_end_condition(session: Session, robot) -> None:
    session.modes.set_regime_override(Regime.OPERATION)
    program(session, "DRIVE J1 TO 20 deg", "DRIVE J1 TO 25 deg UNTIL CONTACT")
    two = session.readiness.view()
    assert not two.ready and two.state.startswith("one motion per step; statements 1 and 2 both move the arm")
    assert two.blocker == refusal_of_submit(session, 0, 2)
    first = session.readiness.view(0, 1)  # no UNTIL, but its path is clear of the cell
    assert first.ready and first.blocker is None and refusal_of_submit(session, 0, 1) is None
    session.modes.set_regime_override(Regime.FREE)
    free = session.readiness.view(0, 1)
    assert free.ready and free.line == "Ready to send 1 (ONLINE: statements go as they are; drags stream to the robot as you drive)"
    assert refusal_of_submit(session, 0, 1) is None


OFFLINE_NEEDS = "OFFLINE: statements 1-2 must be previewed to their end without warnings"
SINGLE_STEP_NEEDS = ("SINGLE STEP: one motion at a time, ended by its UNTIL condition or on a clear path; "
                     "the previous one must be final")


def test_the_submit_tab_line_in_the_offline_and_single_step_regimes_is_the_whole_sentence(session: Session, robot) -> None:
    """The line the Submit tab shows (``needs_html`` of the session's readiness), word for word,
    in the two regimes that are not free, ready and not ready: the regime's name, its condition,
    and where the range stands (or "Ready to send")."""
    from webui.submit_needs import needs_html

    def tab(view) -> str:
        html = needs_html(view)
        assert f'data-submit-ready="{str(view.ready).lower()}" data-regime="{view.regime.value}"' in html
        return html

    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRIVE J1 TO 10 deg", "DRIVE J2 TO -50 deg")
    waiting = session.readiness.view()
    assert waiting.line == f"{OFFLINE_NEEDS} (not yet previewed; Preview and submit previews 1-2 and sends it)"
    assert f">{waiting.line}<" in tab(waiting)
    session.preview.begin(0, 2)
    session.preview.step(2)
    session.preview.end()
    ready = session.readiness.view()
    assert ready.ready and ready.line == f"Ready to send 1-2 ({OFFLINE_NEEDS})"
    assert f">{ready.line}<" in tab(ready)

    session.modes.set_regime_override(Regime.OPERATION)
    two = session.readiness.view()
    assert not two.ready and two.line == f"{SINGLE_STEP_NEEDS} ({two.state})"
    assert two.state == two.blocker.removeprefix("operation regime: ") and "statements 1 and 2 both move the arm" in two.state
    one = session.readiness.view(0, 1)
    assert one.ready and one.line == f"Ready to send 1 ({SINGLE_STEP_NEEDS})"
    assert f">{one.line}<" in tab(one)
    assert refusal_of_submit(session, 0, 1) is None
    wait_until(lambda: len(robot.submitted) == 1, "the single step on the robot's loop")
    assert [e.text for e in session.program.view().entries][:1] == ["DRIVE J2 TO -50 deg"]  # the sent one left
    after = session.readiness.view(0, 1)  # the step just sent is not final yet
    assert after.line == f"{SINGLE_STEP_NEEDS} (waiting until the previous statement is final)"
    assert f">{after.line}<" in tab(after)


def test_without_a_robot_the_line_says_so(session: Session) -> None:
    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRIVE J1 TO 10 deg")
    need = session.readiness.view()
    assert not need.ready and "no robot is configured" in need.state
    assert need.blocker == refusal_of_submit(session, 0, 1)
    assert session.snapshot().readiness == need


def test_readiness_is_republished_when_it_changes(session: Session, robot) -> None:
    got: list = []
    session.subscribe_events(got.append)

    def published() -> list:
        return [e.readiness for e in got if isinstance(e, ReadinessChanged)]

    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRIVE J1 TO 10 deg")
    assert published()[-1].line.startswith("OFFLINE: statements 1 must")
    count = len(published())
    session.program.select(0)  # a program event that changes nothing Submit needs: not republished
    assert len(published()) == count
    session.preview.begin(0, 1)
    session.preview.step(1)
    session.preview.end()
    assert published()[-1].ready
    session.modes.set_regime_override(Regime.OPERATION)
    assert published()[-1].regime is Regime.OPERATION and "SINGLE STEP" in published()[-1].line


def test_preview_and_submit_plays_at_the_preview_speed_then_sends(session: Session, robot, clock) -> None:
    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRIVE J1 TO 40 deg", "DRIVE J2 TO -60 deg")
    with pytest.raises(InputError, match="preview speed"):
        session.preview.set_speed(0)
    assert session.preview.set_speed(10).speed == 10.0
    answer = session.preview.preview_and_submit(0, 2)
    duration = answer.preview.duration
    assert not answer.submitted and answer.preview.playing and answer.preview.then_submit
    assert answer.preview.rate == 10.0 and duration > 2.0
    clock.advance(duration / 10.0 * 0.6)
    session.tick()
    assert session.preview.view().playing and robot.submitted == []  # 60 % of the way: nothing sent
    clock.advance(duration / 10.0 * 0.5)
    session.tick()  # the player reached the end without warnings: the range goes
    assert not session.preview.view().active
    wait_until(lambda: len(robot.submitted) == 1, "the fake has the communication")
    assert [st.kind for st in robot.submitted[0]] == ["DRIVE", "DRIVE"]
    assert len(session.dispatch.view().items) == 2 and session.program.view().empty_index == 0


def test_instant_preview_and_submit_sends_at_once(session: Session, robot) -> None:
    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRIVE J1 TO 30 deg")
    session.preview.set_speed("instant")
    answer = session.preview.preview_and_submit(0, 1)
    assert answer.submitted and answer.sent is not None and not answer.preview.active
    assert [s.text for s in answer.sent.items] == ["DRIVE J1 TO 30 deg"]
    wait_until(lambda: len(robot.submitted) == 1, "the fake has the communication")


def test_an_instant_preview_sent_by_the_players_tick_first_is_reported_as_sent(session: Session, robot, monkeypatch) -> None:
    """The race a headless trial hit: the session's tick (another thread) sends a due range in the
    moment between the preview's publish and the request's own send; the answer must still say
    what was sent, not "not sent"."""
    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRIVE J1 TO 30 deg")
    session.preview.set_speed("instant")
    publish = session.preview._publish
    ticked: list = []

    def publish_then_tick():
        view = publish()
        if not ticked:
            ticked.append(threading.Thread(target=session.tick))
            ticked[0].start()
            ticked[0].join()
        return view

    monkeypatch.setattr(session.preview, "_publish", publish_then_tick)
    answer = session.preview.preview_and_submit(0, 1)
    assert ticked, "the tick ran in the window"
    assert answer.submitted and answer.sent is not None and "sent" in answer.message
    assert [s.text for s in answer.sent.items] == ["DRIVE J1 TO 30 deg"]
    wait_until(lambda: len(robot.submitted) == 1, "the fake has the communication (once)")
    assert len(session.dispatch.view().items) == 1


def test_a_preview_with_warnings_is_not_sent_at_any_speed(session: Session, robot) -> None:
    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRAW TO (550, 0, -600) mm IN BASE")
    got: list = []
    session.subscribe_events(got.append)
    session.preview.set_speed("instant")
    answer = session.preview.preview_and_submit(0, 1)
    assert not answer.submitted and "not sent" in answer.message
    assert answer.preview.active and answer.preview.t == pytest.approx(answer.preview.warnings[0].t)
    assert any(isinstance(e, Notice) and "not sent" in e.message for e in got)
    session.tick()
    assert robot.submitted == [] and session.program.view().empty_index == 1


def test_ending_the_preview_calls_the_send_off(session: Session, robot, clock) -> None:
    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRIVE J1 TO 30 deg")
    answer = session.preview.preview_and_submit(0, 1)  # 1x
    assert answer.preview.then_submit
    session.preview.end()
    clock.advance(answer.preview.duration + 1.0)
    session.tick()
    assert robot.submitted == [] and session.program.view().empty_index == 1


def test_preview_and_submit_is_refused_before_previewing_when_nothing_could_go(session: Session) -> None:
    program(session, "DRIVE J1 TO 30 deg")
    with pytest.raises(ConflictError, match="not started: no robot is configured"):
        session.preview.preview_and_submit(0, 1)
    assert not session.preview.view().active
