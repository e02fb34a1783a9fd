"""The telerobot's safety rules in virtual time (issue 14): no statement can end the process,
stop holds in every state, silence halts the arm, a robot in contact can back away. Each rule
runs on the contact-physics world (the telerobot's) and on the kinematic one.

``Executor`` and ``RobotCore`` run without sockets or clocks; each test is a few hundred servo
ticks at most."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robot_sim.core import RobotCore
from robot_sim.executor import Executor
from robot_sim.settings import WorldSettings
from robot_sim.worlds import make_world
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_program
from shared.language.statements import Draw, Drive, Event, Frame, Move, Moves, Rotate, SetMode, SetSpeed, Speed, SpeedUnit, TaskCall
from shared.wire.messages import (
    AbortFlush,
    HaltCause,
    Halted,
    Heartbeat,
    Hello,
    Rejected,
    RejectReason,
    Resume,
    RobotState,
    SkipCurrent,
    StatementState,
    StatusReport,
    Stop,
    Welcome,
    encode_message,
)
from shared.wire.units import encode_unit

CELL = load_cell(DEFAULT_CELL)
HOME = tuple(float(v) for v in CELL.q_home)
AWAY = tuple(float(v) for v in CELL.q_home + np.radians([20.0, 0, 0, 0, 0, 0]))
SLOW = Speed(value=0.05, unit=SpeedUnit.FRACTION)


ENGINE = {"name": "physics"}


@pytest.fixture(autouse=True, params=["physics", "kinematic"])
def engine(request):
    """Every rule holds on the contact-physics world and on the kinematic one."""
    ENGINE["name"] = request.param
    yield request.param
    ENGINE["name"] = "physics"


def assert_holds(q_now: np.ndarray, q_then: np.ndarray) -> None:
    """The arm held: exactly on the kinematic world; on physics, within what a braked arm settles
    by after a stop (a few 1e-5 rad; 2e-4 rad is 0.2 mm at the tool)."""
    if ENGINE["name"] == "kinematic":
        np.testing.assert_array_equal(q_now, q_then)
    else:
        np.testing.assert_allclose(q_now, q_then, atol=2e-4)


def executor(**world) -> Executor:
    return Executor(CELL, make_world(CELL, WorldSettings(engine=ENGINE["name"], **world)))


def run(ex: Executor, ticks: int) -> list:
    events = []
    for _ in range(ticks):
        events += ex.tick()
    return events


def finals(events) -> dict:
    return {e.number: e for e in events if e.state.final}


def zero_duration(n: int) -> list:
    kinds = [
        Event(name="mark"),
        SetSpeed(speed=Speed(value=0.5, unit=SpeedUnit.FRACTION)),
        SetMode(mode="POSITION"),
        TaskCall(name="release"),
    ]
    return [kinds[i % len(kinds)] for i in range(n)]


# -- the executor survives whatever gets through -------------------------------------------------

NASTY = [
    Drive.model_construct(kind="DRIVE", joint=1, target=math.nan, speed=None, until=None),
    Drive.model_construct(kind="DRIVE", joint=1, target=1e308, speed=None, until=None),
    Drive.model_construct(kind="DRIVE", joint=99, target=0.1, speed=None, until=None),
    Draw.model_construct(kind="DRAW", position=(1e6, 0.0, 0.0), frame=Frame.BASE, speed=None, until=None),
    Draw.model_construct(kind="DRAW", position=(math.inf, 0.0, 0.0), frame=Frame.BASE, speed=None, until=None),
    Moves.model_construct(kind="MOVES", position=(0.4, 0.0, 0.3), rpy=(1e300, 0.0, math.nan), frame=Frame.BASE,
                          speed=None, until=None),
    Rotate.model_construct(kind="ROTATE", rpy=(math.nan,) * 3, frame=Frame.TOOL, speed=None, until=None),
    Move.model_construct(kind="MOVE", joints=(0.0,), speed=None, until=None),
    Move.model_construct(kind="MOVE", joints=(math.nan,) * 6, speed=None, until=None),
]


@pytest.mark.parametrize("statement", NASTY, ids=lambda s: f"{s.kind}")
def test_a_statement_the_planner_cannot_handle_fails_and_the_robot_holds(statement) -> None:
    ex = executor()
    ex.enqueue(1, statement)
    ex.enqueue(2, Event(name="after"))
    done = finals(run(ex, 50))
    assert done[1].state is StatementState.FAILED and done[1].reason
    assert ex.state is RobotState.FAULT and 2 not in done  # holds for the operator
    assert np.all(np.isfinite(ex.q))
    assert ex.resume()[0]
    assert finals(run(ex, 5))[2].state is StatementState.DONE  # and goes on when told


def test_an_exception_of_any_kind_while_planning_fails_only_that_statement(monkeypatch) -> None:
    ex = executor()

    def broken(statement):
        raise ZeroDivisionError("planner bug")

    monkeypatch.setattr(ex.interpreter, "plan_next", broken)
    ex.enqueue(1, Move(joints=AWAY))
    done = finals(run(ex, 3))
    assert done[1].state is StatementState.FAILED
    assert "internal error" in done[1].reason and "ZeroDivisionError: planner bug" in done[1].reason
    assert ex.state is RobotState.FAULT


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    kind=st.sampled_from(["DRIVE", "DRAW", "MOVES", "ROTATE", "MOVE"]),
    values=st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-10, 10)), min_size=6, max_size=6),
    joint=st.integers(-3, 12),
)
def test_fuzzed_numbers_never_escape_the_executor(kind, values, joint) -> None:
    ex = FUZZ_EXECUTOR
    ex.abort()
    ex.drain_events()
    a, b, c, d, e, f = values
    statement = {
        "DRIVE": lambda: Drive.model_construct(kind=kind, joint=joint, target=a, speed=None, until=None),
        "DRAW": lambda: Draw.model_construct(kind=kind, position=(a, b, c), frame=Frame.BASE, speed=None, until=None),
        "MOVES": lambda: Moves.model_construct(kind=kind, position=(a, b, c), rpy=(d, e, f), frame=Frame.WORK,
                                               speed=None, until=None),
        "ROTATE": lambda: Rotate.model_construct(kind=kind, rpy=(a, b, c), frame=Frame.TOOL, speed=None, until=None),
        "MOVE": lambda: Move.model_construct(kind=kind, joints=tuple(values), speed=None, until=None),
    }[kind]()
    ex.enqueue(1, statement)
    for _ in range(3):
        ex.tick()  # must not raise
    assert np.all(np.isfinite(ex.q))
    ex.snapshot()  # the state can still be reported


FUZZ_EXECUTOR = executor(force_noise=0.0)


def test_an_error_escaping_the_servo_tick_holds_the_arm_and_is_reported(monkeypatch) -> None:
    core = greeted_core()
    core.on_unit(encode_unit(1, 0, [Move(joints=AWAY), Event(name="next")], True))
    core.tick()
    assert core.executor.current_number == 1

    def broken():
        raise RuntimeError("sensor bus fell over")

    monkeypatch.setattr(core.executor, "_sense", broken)
    out = core.tick()  # does not raise
    halted = [m for m in out if isinstance(m, Halted)]
    assert halted and halted[0].cause is HaltCause.INTERNAL_ERROR and "sensor bus fell over" in halted[0].detail
    failed = [m for m in out if isinstance(m, StatusReport) and m.state is StatementState.FAILED]
    assert [m.number for m in failed] == [1]
    assert core.executor.state is RobotState.FAULT and [n for n, _ in core.executor.queue] == [2]
    monkeypatch.undo()
    q = core.executor.q.copy()
    for _ in range(20):  # keeps serving, holding
        core.tick()
    assert_holds(core.executor.q, q)
    assert core.on_text(encode_message(Resume(command_id=1)))[-1].applied


def test_a_message_that_makes_the_core_raise_is_refused_and_the_channel_stays(monkeypatch) -> None:
    core = greeted_core()

    def broken(data):
        raise KeyError("oops")

    monkeypatch.setattr(core.receiver, "on_unit", broken)
    (reply,) = core.on_unit(b"whatever")
    assert isinstance(reply, Rejected) and reply.final is False and "KeyError" in reply.detail
    monkeypatch.undo()
    assert any(isinstance(r, StatusReport) for r in core.on_unit(encode_unit(1, 0, [Event(name="ok")], True)))


# -- stop in every state -----------------------------------------------------------------------


def test_stop_while_idle_with_a_queue_holds_it_until_resume() -> None:
    ex = executor()
    ex.enqueue(1, Move(joints=AWAY))
    ex.enqueue(2, Move(joints=HOME))
    assert ex.stop()[0] and ex.state is RobotState.STOPPED
    assert run(ex, 30) == [] and [n for n, _ in ex.queue] == [1, 2]
    ex.enqueue(3, Event(name="late"))  # a statement arriving after the stop waits too
    assert run(ex, 5) == []
    assert ex.resume()[0]
    assert ex.run_until_idle() and not ex.queue


def test_stop_while_idle_and_empty_keeps_the_next_unit_from_starting() -> None:
    core = greeted_core()
    ack = core.on_text(encode_message(Stop(command_id=1)))[-1]
    assert ack.applied and core.executor.state is RobotState.STOPPED
    core.on_unit(encode_unit(1, 0, [Event(name="after_stop")], True))
    for _ in range(20):
        core.tick()
    assert core.executor.current is None and len(core.executor.queue) == 1


def test_stop_in_fault_and_when_stopped_applies_and_changes_nothing() -> None:
    ex = executor()
    ex.enqueue(1, Drive(joint=9, target=0.0))
    ex.enqueue(2, Event(name="next"))
    run(ex, 3)
    assert ex.state is RobotState.FAULT
    assert ex.stop()[0] and ex.state is RobotState.FAULT
    assert ex.resume()[0]
    ex.stop()
    assert ex.stop() == (True, "already stopped") and ex.state is RobotState.STOPPED
    assert run(ex, 5) == []


def test_skip_without_a_current_statement_keeps_the_queue_held() -> None:
    ex = executor()
    ex.enqueue(1, Event(name="a"))
    ex.stop()
    assert not ex.skip(1)[0]
    assert ex.state is RobotState.STOPPED and run(ex, 5) == []
    assert ex.abort()[0] and ex.state is RobotState.IDLE
    assert [e.state for e in ex.drain_events()] == [StatementState.ABORTED]


@pytest.mark.parametrize("stop_after_ticks", [1, 7, 40, 151])
def test_no_statement_starts_after_a_stop_in_a_run_of_zero_duration_statements(stop_after_ticks: int) -> None:
    core = greeted_core()
    core.on_unit(encode_unit(1, 0, zero_duration(300), True))
    for _ in range(stop_after_ticks):
        core.tick()
    started_before = sum(1 for r in core.receiver.reports if r.state is StatementState.RUNNING)
    replies = core.on_text(encode_message(Stop(command_id=1)))
    assert replies[-1].applied
    for i in range(100):
        core.tick()
        core.on_text(encode_message(Heartbeat(seq=i)))
    started_after = sum(1 for r in core.receiver.reports if r.state is StatementState.RUNNING)
    assert started_after == started_before
    assert core.executor.state is RobotState.STOPPED


def test_one_servo_tick_starts_at_most_one_statement() -> None:
    ex = executor()
    for i, s in enumerate(zero_duration(50), start=1):
        ex.enqueue(i, s)
    for _ in range(10):
        assert sum(1 for e in ex.tick() if e.state is StatementState.RUNNING) <= 1


# -- recovery from contact (finding 13) ---------------------------------------------------------


def test_a_gripper_on_the_plate_can_back_away_and_cannot_press_further() -> None:
    ex = executor(seed=2)
    prog = parse_program(
        "MOVES TO (0, -30, 120) mm (180, 0, 0) deg IN WORK\n"
        "DRAW TO (0, -30, -20) mm IN WORK\n"  # the gripper into the plate
        "DRAW TO (0, -30, -30) mm IN WORK\n"  # presses further
        "DRIVE J2 TO -40 deg\n"  # a drive away
        "DRAW TO (0, -30, 100) mm IN WORK"  # straight up
    ).statements
    for i, s in enumerate(prog, start=1):
        ex.enqueue(i, s)
    done = finals(ex.run_until_idle())
    assert done[2].state is StatementState.FAILED and "unplanned contact" in done[2].reason
    assert ex.resume()[0]
    done.update(finals(ex.run_until_idle()))
    assert done[3].state is StatementState.FAILED and "unplanned contact" in done[3].reason
    assert ex.resume()[0]
    done.update(finals(ex.run_until_idle()))
    assert done[4].state is StatementState.DONE and done[5].state is StatementState.DONE, done[5].reason


PEG_INTO_PLATE = [
    "MOVES TO (0, -80, 160) mm (180, 0, 0) deg IN WORK",
    "DRAW TO (0, -80, 75) mm IN WORK",
    "TASK grasp(peg)",
    "TASK extract_peg(peg, HOLE1)",
    "DRAW TO (0, -30, 120) mm IN WORK",
    "DRAW TO (0, -30, 60) mm IN WORK",  # drives the peg into the plate top: contact fault
]


@pytest.mark.parametrize(
    "after, outcome",
    [
        ("DRAW TO (0, -30, 140) mm IN WORK", StatementState.DONE),  # straight up
        ("DRAW TO (10, -30, 140) mm IN WORK", StatementState.DONE),  # up and aside
        ("MODE FORCE\nDRAW TO (0, -30, 130) mm IN WORK UNTIL TIME 0.5 s", StatementState.DONE),
        ("DRAW TO (0, -30, 55) mm IN WORK", StatementState.FAILED),  # presses further
    ],
)
def test_a_peg_pressed_on_the_plate_backs_away_after_the_fault(after: str, outcome: StatementState) -> None:
    ex = executor(seed=2)
    prog = parse_program("\n".join(PEG_INTO_PLATE)).statements
    for i, s in enumerate(prog, start=1):
        ex.enqueue(i, s)
    done = finals(ex.run_until_idle())
    assert done[6].state is StatementState.FAILED and "unplanned contact" in done[6].reason
    assert ex.world.contact(ex.q, noise=False).magnitude > 0.99 * ex.settings.contact_limit  # still pressing
    assert ex.resume()[0]
    tail = parse_program(after).statements
    for i, s in enumerate(tail, start=7):
        ex.enqueue(i, s)
    done.update(finals(ex.run_until_idle()))
    last = done[6 + len(tail)]
    assert last.state is outcome, last.reason
    if outcome is StatementState.FAILED:
        assert "pressing further" in last.reason
    else:
        assert not ex.world.contact(ex.q, noise=False).touching


# -- silence ------------------------------------------------------------------------------------


def greeted_core(**kw) -> RobotCore:
    core = RobotCore(executor(force_noise=0.0), session_id="unit", **kw)
    core.connect()
    replies = core.on_text(encode_message(Hello(client_id="c")))
    assert isinstance(replies[0], Welcome)
    return core


def ticks_for(core: RobotCore, seconds: float) -> int:
    return int(round(seconds / core.executor.dt))


def test_silence_past_the_limit_stops_a_running_arm_and_says_why() -> None:
    core = greeted_core()
    core.on_unit(encode_unit(1, 0, [Move(joints=AWAY, speed=SLOW), Move(joints=HOME, speed=SLOW)], True))
    out = []
    for _ in range(ticks_for(core, 1.15)):
        out += core.tick()
    assert core.executor.state is RobotState.RUNNING and not any(isinstance(m, Halted) for m in out)
    for _ in range(ticks_for(core, 0.1)):
        out += core.tick()
    (halted,) = [m for m in out if isinstance(m, Halted)]
    assert halted.cause is HaltCause.SILENCE
    assert halted.detail.startswith("no message from the console for 1.2 s (limit 1.0 s beyond the 0.2 s heartbeat)")
    assert core.executor.state is RobotState.STOPPED and core.executor.halted == halted.detail
    q = core.executor.q.copy()
    for _ in range(50):
        core.tick()
    assert_holds(core.executor.q, q)  # holds
    # the heartbeats kept flowing all along, one every 0.2 s
    beats = [m for m in out if isinstance(m, Heartbeat)]
    assert [b.seq for b in beats] == list(range(len(beats))) and len(beats) == 6
    # the operator's resume continues the same motion
    ack = core.on_text(encode_message(Resume(command_id=1)))[-1]
    assert ack.applied and core.executor.state is RobotState.RUNNING and core.executor.halted is None


def test_heartbeats_from_the_console_keep_the_arm_going() -> None:
    core = greeted_core()
    core.on_unit(encode_unit(1, 0, [Move(joints=AWAY, speed=SLOW), Move(joints=HOME, speed=SLOW)], True))
    for i in range(ticks_for(core, 4.0)):
        core.tick()
        if i % 20 == 0:
            assert core.on_text(encode_message(Heartbeat(seq=i))) == []
    assert core.executor.halted is None and core.executor.state is RobotState.RUNNING


def test_an_idle_robot_is_not_stopped_by_silence_and_a_later_unit_runs() -> None:
    core = greeted_core()
    for _ in range(ticks_for(core, 3.0)):
        core.tick()
    assert core.executor.state is RobotState.IDLE and core.executor.halted is None
    core.on_unit(encode_unit(1, 0, [Event(name="later")], True))
    core.tick()
    assert core.receiver.reports[-1].state is StatementState.DONE


def test_a_closed_connection_stops_the_arm_at_the_limit_and_the_halt_reaches_the_next_console() -> None:
    core = greeted_core(silence_limit_s=0.5)
    core.on_unit(encode_unit(1, 0, [Move(joints=AWAY, speed=SLOW), Move(joints=HOME, speed=SLOW)], True))
    for _ in range(10):
        core.tick()
    core.disconnect()  # heard last at 0 s (the units); the limit is reached at 0.7 s
    for _ in range(ticks_for(core, 0.55)):
        core.tick()
    assert core.executor.state is RobotState.RUNNING  # within heartbeat + limit nothing changes
    for _ in range(ticks_for(core, 0.1)):
        core.tick()
    assert core.executor.state is RobotState.STOPPED
    core.connect()
    replies = core.on_text(encode_message(Hello(client_id="c", session_id="unit")))
    welcome = replies[0]
    assert isinstance(welcome, Welcome) and welcome.halted and "limit 0.5 s" in welcome.halted
    assert welcome.silence_limit_s == 0.5 and welcome.heartbeat_s == 0.2
    assert any(isinstance(m, Halted) and m.cause is HaltCause.SILENCE for m in replies)
    for _ in range(20):
        core.tick()
    assert core.executor.state is RobotState.STOPPED  # the reconnect does not resume by itself
    assert core.on_text(encode_message(Resume(command_id=1)))[-1].applied


def test_a_reconnect_within_the_limit_changes_nothing() -> None:
    core = greeted_core()
    core.on_unit(encode_unit(1, 0, [Move(joints=AWAY, speed=SLOW), Move(joints=HOME, speed=SLOW)], True))
    for _ in range(10):
        core.tick()
    core.disconnect()
    for _ in range(ticks_for(core, 0.8)):
        core.tick()
    core.connect()
    assert core.on_text(encode_message(Hello(client_id="c", session_id="unit")))[0].halted is None
    for _ in range(ticks_for(core, 0.5)):
        core.tick()
    assert core.executor.state is RobotState.RUNNING and core.executor.halted is None


# -- the bounded buffer ---------------------------------------------------------------------------


def test_a_communication_that_would_overflow_the_buffer_is_refused_whole() -> None:
    ex = Executor(CELL, make_world(CELL, WorldSettings(engine=ENGINE["name"])), settings=type(executor().settings)(max_queue=10))
    core = RobotCore(ex, session_id="small")
    core.connect()
    core.on_text(encode_message(Hello(client_id="c")))
    core.on_unit(encode_unit(1, 0, [Event(name="e")] * 8, True))
    (rej,) = core.on_unit(encode_unit(2, 0, [Event(name="e")] * 3, True))
    assert isinstance(rej, Rejected) and rej.reason is RejectReason.BUFFER_FULL and rej.final and rej.comm_id == 2
    assert len(ex.queue) == 8 and core.receiver.next_number == 9
    replies = core.on_unit(encode_unit(3, 0, [Event(name="e")] * 2, True))
    assert replies[0].type == "accepted" and len(ex.queue) == 10


def test_skip_and_abort_still_work_in_a_halted_robot() -> None:
    core = greeted_core()
    core.on_unit(encode_unit(1, 0, [Move(joints=AWAY, speed=SLOW), Move(joints=HOME, speed=SLOW)], True))
    for _ in range(ticks_for(core, 1.5)):
        core.tick()
    assert core.executor.halted
    assert core.on_text(encode_message(SkipCurrent(command_id=1, number=1)))[-1].applied
    assert core.executor.halted is None
    core.on_text(encode_message(Stop(command_id=2)))
    assert core.on_text(encode_message(AbortFlush(command_id=3)))[-1].applied
    assert not core.executor.busy and core.executor.state is RobotState.IDLE
