"""The console session against an in-memory robot (the ``RobotLink`` seam of
``server.console.robot_seam``): submission and numbering, status reports (also before their
numbers), a rejected communication, a robot restart, STOP whoever holds control, the quasi
regime's preview rule and the link view of the robot's health.

The fake runs its coroutines on a real asyncio loop in a background thread, as the robot client
does; the session runs in virtual time (``clock``), which the fake advances to stand for the
link's round trip."""

from __future__ import annotations

import asyncio
import math
import threading
import time
from collections.abc import Callable, Iterable

import pytest

from server.console import (
    Caller,
    ConflictError,
    ControlLockError,
    Notice,
    Regime,
    SentChanged,
    SentStatus,
    Session,
)
from server.console.robot_seam import RobotLink
from server.robot_client import ChannelHealth, CommunicationRejected, RobotClient
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel
from shared.language.parser import parse_statement
from shared.language.statements import Statement
from shared.wire.messages import (
    ControlMode,
    RecoveryAck,
    Rejected,
    RejectReason,
    RobotSnapshot,
    RobotState,
    StatementState,
    StatusReport,
)
from shared.wire.session import SessionRestart
from shared.wire.telemetry import TelemetryFrame

WAIT_S = 10.0  # real seconds a background step may take on a busy machine


def wait_until(condition: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + WAIT_S
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting until {what}")
        time.sleep(0.002)


def healthy(**changes) -> ChannelHealth:
    values = {"connected": True, "command": "live", "heard_ago_s": 0.1, "silence_limit_s": 1.5, "telemetry": "none",
              "telemetry_ago_s": None, "halted": None, "errors": 0, "last_error": None, "refused": None,
              "buffer_full": None, "session_id": "robot-s1", "restarts": 0}
    values.update(changes)
    return ChannelHealth(**values)


class FakeRobot:
    """A robot in memory: numbers statements from 1, answers recovery commands, and reports
    what a test tells it to. ``gate``/``recovery_gate`` (when set to a closed event) hold a
    submission / a recovery command until the test opens them; ``round_trip`` is how far the
    virtual clock moves while a submission is on the way; ``reject`` makes the next submission
    fail with that exception."""

    def __init__(self, clock, loop: asyncio.AbstractEventLoop, url: str = "fake://robot") -> None:
        self.url = url
        self.reconnects = 0
        self.connected = threading.Event()
        self.connected.set()
        self._clock, self._loop = clock, loop
        self._health = healthy()
        self._reports: list[Callable[[StatusReport], None]] = []
        self._frames: list[Callable[[TelemetryFrame], None]] = []
        self._restarts: list[Callable[[SessionRestart], None]] = []
        self.submitted: list[list[Statement]] = []
        self.recoveries: list[str] = []
        self.next_number = 1
        self.round_trip = 0.0
        self.reject: Exception | None = None
        self.gate: threading.Event | None = None
        self.recovery_gate: threading.Event | None = None
        self._seq = 0

    # -- the seam ------------------------------------------------------------------------------
    def health(self) -> ChannelHealth:
        return self._health

    def on_report(self, listener: Callable[[StatusReport], None]) -> None:
        self._reports.append(listener)

    def on_telemetry(self, listener: Callable[[TelemetryFrame], None],
                     gate: Callable[[TelemetryFrame], bool] | None = None) -> None:
        # as the client does: the gate where the frame arrives, the listener for what it lets through
        self._frames.append(listener if gate is None else lambda frame: gate(frame) and listener(frame))

    def on_account(self, listener) -> None: ...

    def on_restart(self, listener: Callable[[SessionRestart], None]) -> None:
        self._restarts.append(listener)

    async def submit(self, statements: Iterable[Statement], timeout: float | None = None) -> tuple[int, ...]:
        statements = list(statements)
        self.submitted.append(statements)
        await self._wait(self.gate)
        self._clock.advance(self.round_trip)
        if self.reject is not None:
            exc, self.reject = self.reject, None
            raise exc
        first, self.next_number = self.next_number, self.next_number + len(statements)
        return tuple(range(first, self.next_number))

    async def stop(self, timeout: float | None = None) -> RecoveryAck:
        return await self._recover("stop")

    async def resume(self, timeout: float | None = None) -> RecoveryAck:
        return await self._recover("resume")

    async def skip(self, number: int, timeout: float | None = None) -> RecoveryAck:
        return await self._recover(f"skip {number}")

    async def abort(self, timeout: float | None = None) -> RecoveryAck:
        return await self._recover("abort")

    # -- what the test makes it do -------------------------------------------------------------
    async def _wait(self, gate: threading.Event | None) -> None:
        while gate is not None and not gate.is_set():
            await asyncio.sleep(0.002)

    async def _recover(self, what: str) -> RecoveryAck:
        self.recoveries.append(what)
        await self._wait(self.recovery_gate)
        return RecoveryAck(command_id=len(self.recoveries), applied=True)

    def _on_loop(self, listeners, message) -> None:
        """Call the listeners on the loop's thread, as the robot client does, and wait."""
        async def call() -> None:
            for listener in listeners:
                listener(message)

        asyncio.run_coroutine_threadsafe(call(), self._loop).result(WAIT_S)

    def report(self, number: int, state: StatementState, q=None, reason: str | None = None) -> None:
        self._seq += 1
        robot = None
        if state in (StatementState.DONE, StatementState.FAILED):
            robot = RobotSnapshot(state=RobotState.IDLE, q=tuple(float(v) for v in q), base_p_tool=(0.5, 0.0, -0.2),
                                  tool_rpy=(math.pi, 0.0, 0.0))
        self._on_loop(self._reports, StatusReport(report_seq=self._seq, number=number, state=state, reason=reason, robot=robot))

    def frame(self, q, state: RobotState, statement: int = 0) -> None:
        self._on_loop(self._frames, TelemetryFrame(time=0.0, frame=1, state=state, mode=ControlMode.POSITION, statement=statement,
                                                   q=tuple(float(v) for v in q), position=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)))

    def restart(self, restart: SessionRestart) -> None:
        self._on_loop(self._restarts, restart)

    def set_health(self, **changes) -> None:
        self._health = healthy(**changes)

    def open_gates(self) -> None:
        for gate in (self.gate, self.recovery_gate):
            if gate is not None:
                gate.set()


@pytest.fixture(scope="module")
def cell_and_scene():
    """The conftest's cell with a coarser collision hierarchy: built in a fraction of the time,
    the same answers (the leaves are tested triangle against triangle)."""
    cell = load_cell(DEFAULT_CELL)
    return cell, SceneModel.from_cell(cell, leaf_size=8)


@pytest.fixture
def robot(session: Session, loop, clock):
    fake = FakeRobot(clock, loop)
    session.attach_robot(fake, loop)
    yield fake
    fake.open_gates()


@pytest.fixture
def events(session: Session) -> list:
    got: list = []
    session.subscribe_events(got.append)
    return got


def statuses(session: Session) -> list[SentStatus]:
    return [s.status for s in session.dispatch.view().items]


def program(session: Session, *lines: str) -> None:
    for line in lines:
        session.program.insert(line)


def test_the_fake_and_the_real_client_are_robot_links(robot) -> None:
    assert isinstance(robot, RobotLink)
    assert isinstance(RobotClient("ws://127.0.0.1:1"), RobotLink)  # constructing it connects nowhere
    assert not isinstance(object(), RobotLink)


def test_submit_sends_numbers_and_reports_move_the_statements_through_their_statuses(session, robot, clock, events) -> None:
    session.modes.set_regime_override(Regime.FREE)
    program(session, "DRIVE J1 TO 10 deg", "DRIVE J2 TO -50 deg")
    robot.gate = threading.Event()
    t_submit = clock.t
    view = session.dispatch.submit(0, 2)
    # the statements left the program at once and are listed as sending, without numbers
    assert [s.text for s in view.items] == ["DRIVE J1 TO 10 deg", "DRIVE J2 TO -50 deg"]
    assert [s.status for s in view.items] == [SentStatus.SENDING] * 2 and view.pending == 2
    assert all(s.number is None and s.submitted_at == t_submit for s in view.items)
    assert session.program.view().empty_index == 0
    # the program now starts where they are predicted to end
    start = session.program.view()
    assert start.start_source == "predicted"
    assert start.start_q[0] == pytest.approx(math.radians(10.0)) and start.start_q[1] == pytest.approx(math.radians(-50.0))
    wait_until(lambda: len(robot.submitted) == 1, "the fake has the communication")
    assert robot.submitted[0] == [parse_statement("DRIVE J1 TO 10 deg"), parse_statement("DRIVE J2 TO -50 deg")]
    assert statuses(session) == [SentStatus.SENDING] * 2
    # the robot answers after 0.5 s here and 0.2 s on the way back
    clock.advance(0.5)
    robot.round_trip = 0.2
    robot.gate.set()
    wait_until(lambda: statuses(session) == [SentStatus.RECEIVED] * 2, "the numbers arrive")
    items = session.dispatch.view().items
    assert [s.number for s in items] == [1, 2]
    assert all(s.answered_at == pytest.approx(t_submit + 0.7) for s in items)
    link = session.link.view()
    assert link.round_trip_s == pytest.approx(0.7) and link.delay_s == pytest.approx(0.35)
    # reports: running, then done, each stamped on the console's clock
    home = session.cell.q_home
    clock.advance(1.0)
    robot.report(1, StatementState.RUNNING)
    t_run1 = clock.t
    clock.advance(0.8)
    q1 = home.copy()
    q1[0] = math.radians(10.0)
    robot.report(1, StatementState.DONE, q=q1)
    t_done1 = clock.t
    first = session.dispatch.view().items[0]
    assert first.status is SentStatus.DONE
    assert (first.started_at, first.finished_at) == (t_run1, t_done1) and first.run_s == pytest.approx(0.8)
    assert session.dispatch.view().items[1].status is SentStatus.RECEIVED
    robot.report(2, StatementState.RUNNING)
    clock.advance(0.3)
    q2 = q1.copy()
    q2[1] = math.radians(-50.0)
    robot.report(2, StatementState.DONE, q=q2)
    done = session.dispatch.view()
    assert [s.status for s in done.items] == [SentStatus.DONE] * 2 and done.pending == 0
    assert done.items[1].run_s == pytest.approx(0.3)
    assert any(isinstance(e, SentChanged) and e.sent.items[0].status is SentStatus.DONE for e in events)


def test_a_report_before_its_number_is_kept_until_the_numbers_come(session, robot, clock) -> None:
    session.modes.set_regime_override(Regime.FREE)
    program(session, "DRIVE J1 TO 10 deg", "DRIVE J2 TO -50 deg")
    robot.gate = threading.Event()
    session.dispatch.submit(0, 2)
    wait_until(lambda: len(robot.submitted) == 1, "the fake has the communication")
    # the robot ran statement 1 and started statement 2 before its answer reached the console
    q1 = session.cell.q_home.copy()
    q1[0] = math.radians(10.0)
    robot.report(1, StatementState.RUNNING)
    robot.report(1, StatementState.DONE, q=q1)
    robot.report(2, StatementState.RUNNING)
    assert statuses(session) == [SentStatus.SENDING] * 2  # nothing to tie them to yet
    clock.advance(0.4)
    robot.gate.set()
    wait_until(lambda: [s.number for s in session.dispatch.view().items] == [1, 2], "the numbers arrive")
    items = session.dispatch.view().items
    assert [s.status for s in items] == [SentStatus.DONE, SentStatus.RUNNING]
    assert items[0].finished_at is not None and items[1].started_at is not None and items[1].finished_at is None


def test_a_rejected_communication_marks_all_its_statements_rejected(session, robot, clock, events) -> None:
    session.modes.set_regime_override(Regime.FREE)
    program(session, "DRIVE J1 TO 10 deg", "DRIVE J2 TO -50 deg")
    answer = Rejected(comm_id=1, reason=RejectReason.BUFFER_FULL, detail="room for 0 statements")
    robot.reject = CommunicationRejected(answer, statements=2)
    session.dispatch.submit(0, 2)
    wait_until(lambda: statuses(session) == [SentStatus.REJECTED] * 2, "the rejection arrives")
    items = session.dispatch.view().items
    assert all(s.number is None and s.finished_at is not None for s in items)
    assert all("robot buffer full" in s.reason and "room for 0 statements" in s.reason for s in items)
    assert session.dispatch.view().pending == 0
    assert session.program.start.unknown  # what was predicted did not happen
    # the notice follows on the loop's thread
    wait_until(lambda: any(isinstance(e, Notice) and e.level == "error" and "robot buffer full" in e.message for e in events),
               "the rejection's notice")
    # the next communication is numbered from where the robot stands
    session.program.insert("DRIVE J3 TO 190 deg")
    session.dispatch.submit(0, 1)
    wait_until(lambda: statuses(session)[-1] is SentStatus.RECEIVED, "the next answer")
    assert session.dispatch.view().items[-1].number == 1


def test_a_robot_restart_leaves_numbered_unfinished_statements_unknown(session, robot, clock, events) -> None:
    session.modes.set_regime_override(Regime.FREE)
    program(session, "DRIVE J1 TO 10 deg", "DRIVE J2 TO -50 deg", "DRIVE J3 TO 190 deg")
    session.dispatch.submit(0, 3)
    wait_until(lambda: statuses(session) == [SentStatus.RECEIVED] * 3, "the numbers arrive")
    q1 = session.cell.q_home.copy()
    q1[0] = math.radians(10.0)
    robot.report(1, StatementState.RUNNING)
    robot.report(1, StatementState.DONE, q=q1)
    robot.report(2, StatementState.RUNNING)
    # a second communication is still on its way when the robot comes back as a new session
    robot.gate = threading.Event()
    session.program.insert("DRIVE J1 TO 0 deg")
    session.dispatch.submit(0, 1)
    wait_until(lambda: len(robot.submitted) == 2, "the second communication is on its way")
    clock.advance(2.0)
    restart = SessionRestart(old_session="robot-s1", new_session="robot-s2", comms=(2,), commands=(), numbers=(2, 3))
    robot.restart(restart)
    items = session.dispatch.view().items
    assert [s.status for s in items] == [SentStatus.DONE, SentStatus.UNKNOWN, SentStatus.UNKNOWN, SentStatus.SENDING]
    assert items[1].reason == items[2].reason == restart.describe()
    assert items[1].finished_at == items[2].finished_at == clock.t
    assert session.program.start.unknown
    assert any(isinstance(e, Notice) and e.level == "error" and "robot restarted" in e.message for e in events)
    # a report of the old session's numbers no longer changes anything
    robot.report(3, StatementState.RUNNING)
    assert session.dispatch.view().items[2].status is SentStatus.UNKNOWN


def test_stop_reaches_the_robot_whoever_holds_control(session, robot, events) -> None:
    grant = session.control.request("alice")
    robot.recovery_gate = threading.Event()
    view = session.recovery.stop()  # the page holds no token
    assert view.recovery_pending == ["stop"]
    wait_until(lambda: robot.recoveries == ["stop"], "the fake has the stop")
    robot.recovery_gate.set()
    wait_until(lambda: session.link.view().recovery_pending == [], "the stop is acknowledged")
    wait_until(lambda: any(isinstance(e, Notice) and e.message == "robot applied stop" for e in events), "the stop's notice")
    session.recovery.stop(client="bob")
    wait_until(lambda: robot.recoveries == ["stop", "stop"], "bob's stop reaches the fake")
    # the other recovery commands need control
    with pytest.raises(ControlLockError):
        session.recovery.resume(client="bob")
    with pytest.raises(ControlLockError):
        session.recovery.abort()
    with pytest.raises(ControlLockError):
        session.dispatch.submit(0, 0, client="bob")
    session.recovery.resume(client=Caller("alice", grant.token))
    wait_until(lambda: robot.recoveries == ["stop", "stop", "resume"], "alice's resume reaches the fake")


def test_the_quasi_regime_refuses_submit_until_the_range_was_previewed_to_its_end(session, robot) -> None:
    session.modes.set_regime_override(Regime.QUASI)
    program(session, "DRIVE J1 TO 10 deg", "DRIVE J2 TO -50 deg")
    with pytest.raises(ConflictError, match="quasi"):
        session.dispatch.submit(0, 2)
    # previewed part of the way: still refused
    session.preview.begin(0, 2)
    session.preview.step(1)
    with pytest.raises(ConflictError, match="previewed"):
        session.dispatch.submit(0, 2)  # and never while previewing
    session.preview.end()
    with pytest.raises(ConflictError, match="quasi"):
        session.dispatch.submit(0, 2)
    # only the first statement previewed to its end: it may go, the two may not
    session.preview.begin(0, 1)
    session.preview.step(1)
    session.preview.end()
    assert session.program.view().confirmed == (0, 1)
    with pytest.raises(ConflictError, match="quasi"):
        session.dispatch.submit(0, 2)
    assert robot.submitted == [] and session.dispatch.view().items == []
    assert session.program.view().empty_index == 2  # nothing left the program
    # both, to the end
    view = session.preview.begin(0, 2)
    assert not view.warnings
    session.preview.step(1)
    end = session.preview.step(1)
    assert end.t == pytest.approx(view.duration)
    session.preview.end()
    assert session.program.view().confirmed == (0, 2)
    robot.gate = threading.Event()
    sent = session.dispatch.submit(0, 2)
    assert [s.status for s in sent.items] == [SentStatus.SENDING] * 2
    wait_until(lambda: len(robot.submitted) == 1, "the fake has the communication")
    assert [st.kind for st in robot.submitted[0]] == ["DRIVE", "DRIVE"]
    assert session.program.view().confirmed is None  # a confirmation is spent by the submission


def test_the_link_view_reports_the_robots_health(session, robot, clock) -> None:
    robot.reconnects = 2
    robot.set_health(heard_ago_s=0.3, session_id="robot-s7", restarts=1)
    view = session.link.view()
    assert view.configured and view.url is None and view.connected and view.status == "live"  # no address published
    assert session.link.view(address=True).url == "fake://robot"
    assert view.heard_ago_s == 0.3 and view.silence_limit_s == 1.5
    assert view.robot_session == "robot-s7" and view.robot_restarts == 1 and view.reconnects == 2
    assert view.problems == [] and view.robot_state is None  # no telemetry yet
    # a live telemetry frame: the robot's state shows, with its age on the console's clock
    robot.set_health(telemetry="live", telemetry_ago_s=0.02, telemetry_frames=7)
    robot.frame(session.cell.q_home, RobotState.RUNNING, statement=1)
    clock.advance(0.25)
    view = session.link.view()
    assert view.robot_state == "running" and view.telemetry == "live" and view.telemetry_frames == 7
    assert view.telemetry_received_ago_s == pytest.approx(0.25)
    # stale telemetry never shows an old state
    robot.set_health(telemetry="stale", telemetry_ago_s=2.5)
    view = session.link.view()
    assert view.robot_state is None and "telemetry stale (2.5 s)" in view.problems
    # the link down, the robot halted by itself, its buffer full, an error handling a message
    robot.set_health(connected=False, command="down", heard_ago_s=None, halted="console silent for 1.5 s",
                     buffer_full="room for 0 statements", errors=1, last_error="status: ValueError: bad")
    view = session.link.view()
    assert not view.connected and view.status == "down"
    assert view.halted == "console silent for 1.5 s" and view.errors == 1
    assert view.problems == [
        "link down", "robot halted by itself: console silent for 1.5 s", "robot buffer full: room for 0 statements",
        "1 error(s) handling the robot's messages; last: status: ValueError: bad",
    ]
    robot.set_health(command="silent", heard_ago_s=3.25)
    assert session.link.view().problems == ["robot silent for 3.2 s"]
