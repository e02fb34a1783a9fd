"""Console end, delayed link and telerobot, all sans-I/O, in virtual time.

``CommandSender`` (the console's end) talks to ``RobotCore`` through ``LinkCore`` with the
thesis's 3 s each way; one loop advances a virtual clock by the robot's servo period. Minutes of
robot time run in seconds, so the properties the issue asks for are checked on whole programs:
every statement ends exactly once, cuts of the link lose nothing and run nothing twice, stop
overtakes a full buffer, malformed units never change the robot's state.
"""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robot_sim.core import RobotCore
from robot_sim.executor import Executor
from robot_sim.world import SimWorld, WorldSettings
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_program
from shared.language.statements import Move
from shared.link.core import Direction, LinkCore, LinkFault, LinkParams
from shared.paths import ASSETS_DIR
from shared.wire.liveness import HEARTBEAT_INTERVAL_S
from shared.wire.messages import (
    MAX_ROBOT_MESSAGE_BYTES,
    Heartbeat,
    Rejected,
    Resume,
    RobotState,
    StatementState,
    Stop,
    decode_message,
    encode_message,
)
from shared.wire.session import CommandSender
from shared.wire.units import encode_unit

CELL = load_cell(DEFAULT_CELL)
PEG_TRANSFER = parse_program((ASSETS_DIR / "programs" / "peg_transfer.tp").read_text()).statements
FINAL = {StatementState.DONE, StatementState.FAILED, StatementState.SKIPPED, StatementState.ABORTED}


class VirtualSession:
    """Console sender, link and robot on one virtual clock; the link can be cut and reopened.

    The console sends a heartbeat every ``HEARTBEAT_INTERVAL_S`` while the link is open (as the
    real console does), so the robot's silence watch hears it through the delay."""

    def __init__(self, delay: float = 3.0, **world: object) -> None:
        self.robot = RobotCore(Executor(CELL, SimWorld(CELL, CELL.robot, WorldSettings(**world))), session_id="virtual")
        self.sender = CommandSender("console-test")
        self.params = LinkParams(delay_s=delay)
        self.now = 0.0
        self.link: LinkCore | None = None
        self.received: list = []  # every message the console got, in order
        self.heartbeats = True
        self._next_heartbeat = 0.0
        self._heartbeat_seq = 0
        self.open()

    # -- connection -------------------------------------------------------------------------
    def open(self) -> None:
        self.link = LinkCore(self.params)
        self.robot.connect()
        self._up(encode_message(self.sender.hello()))

    def cut(self) -> None:
        """The link breaks: whatever is in flight both ways is gone."""
        assert self.link is not None
        self.link.cut()
        self.link = None
        self.robot.disconnect()

    # -- traffic ------------------------------------------------------------------------------
    def _up(self, payload: bytes | str) -> None:
        if self.link is not None:
            self.link.send(self.now, Direction.UP, payload)

    def _down(self, messages: list) -> None:
        for m in messages:
            if self.link is not None:
                self.link.send(self.now, Direction.DOWN, encode_message(m))

    def submit(self, statements) -> int:
        comm_id, units = self.sender.submit(list(statements))
        for u in units:
            self._up(u)
        return comm_id

    def command(self, kind, **fields) -> None:
        self._up(encode_message(self.sender.command(kind, **fields)))

    def raw_up(self, payload: bytes | str) -> None:
        self._up(payload)

    def step(self) -> None:
        self.now += self.robot.executor.dt
        if self.heartbeats and self.link is not None and self.now >= self._next_heartbeat:
            self._up(encode_message(Heartbeat(seq=self._heartbeat_seq)))
            self._heartbeat_seq += 1
            self._next_heartbeat = self.now + HEARTBEAT_INTERVAL_S
        if self.link is not None:
            for item in self.link.poll(self.now):
                if isinstance(item, LinkFault):
                    self.cut()
                    break
                if item.direction is Direction.UP:
                    data = item.payload
                    self._down(self.robot.on_unit(data) if isinstance(data, bytes) else self.robot.on_text(data))
                else:
                    msg = decode_message(item.payload, max_bytes=MAX_ROBOT_MESSAGE_BYTES)
                    self.received.append(msg)
                    if msg.type == "welcome":
                        for again in self.sender.on_welcome(msg):
                            self._up(again if isinstance(again, bytes) else encode_message(again))
                    else:
                        self.sender.on_message(msg)
        self._down(self.robot.tick())

    def run(self, seconds: float) -> None:
        end = self.now + seconds
        while self.now < end:
            self.step()

    def run_until_final(self, numbers, limit: float = 600.0) -> None:
        end = self.now + limit
        while self.now < end and any(self.sender.final_state(n) is None for n in numbers):
            self.step()

    # -- what the robot did ------------------------------------------------------------------
    def robot_finals(self) -> Counter:
        return Counter(r.number for r in self.robot.receiver.reports if r.state in FINAL)

    def robot_runs(self) -> Counter:
        return Counter(r.number for r in self.robot.receiver.reports if r.state is StatementState.RUNNING)


def test_peg_transfer_through_a_3_s_link_in_virtual_time() -> None:
    s = VirtualSession()
    s.submit(PEG_TRANSFER)
    numbers = tuple(range(1, len(PEG_TRANSFER) + 1))
    s.run_until_final(numbers)
    assert all(s.sender.final_state(n) is StatementState.DONE for n in numbers)
    assert s.robot.executor.world.pegs["peg"].in_hole == "HOLE2"
    assert set(s.robot_finals().values()) == {1} and set(s.robot_runs().values()) == {1}
    # the console learns of the last status one delay after the robot reported it
    last = max(r.report_seq for r in s.robot.receiver.reports)
    assert s.sender.last_report_seq == last
    # the round trip costs the two delays: the program's 16-20 s of motion plus 6 s
    assert 22.0 < s.now < 30.0


@pytest.mark.parametrize("cut_at", [1.0, 3.2, 9.5, 15.0])
def test_cutting_the_link_mid_program_loses_nothing_and_runs_nothing_twice(cut_at: float) -> None:
    s = VirtualSession()
    s.submit(PEG_TRANSFER)
    s.run(cut_at)
    s.cut()
    s.run(2.0)  # the robot starts nothing new; past the silence limit it stops and holds
    assert s.robot.executor.hold_queue
    s.open()
    s.run(2 * s.params.delay_s + 0.1)  # the welcome is back
    welcome = [m for m in s.received if m.type == "welcome"][-1]
    if s.robot.executor.busy and cut_at > s.params.delay_s:  # it had statements: silence halted them
        assert s.robot.executor.state is RobotState.STOPPED and welcome.halted
        assert any(m.type == "halted" and m.cause.value == "silence" for m in s.received)
        s.command(Resume)  # the operator's recovery
    numbers = tuple(range(1, len(PEG_TRANSFER) + 1))
    s.run_until_final(numbers)
    assert all(s.sender.final_state(n) is StatementState.DONE for n in numbers), s.sender.statuses
    assert set(s.robot_finals().values()) == {1}
    assert set(s.robot_runs().values()) == {1}
    assert s.robot.receiver.next_number == len(PEG_TRANSFER) + 1  # numbered once
    assert s.robot.executor.world.pegs["peg"].in_hole == "HOLE2"


def test_stop_overtakes_a_full_buffer() -> None:
    s = VirtualSession(delay=0.5)
    home = tuple(float(v) for v in CELL.q_home)
    away = tuple(float(v) for v in CELL.q_home + np.radians([20.0, 0, 0, 0, 0, 0]))
    program = [Move(joints=away if i % 2 == 0 else home) for i in range(1000)]
    s.submit(program)
    s.run(2.0)
    assert s.robot.executor.current_number >= 1 and len(s.robot.executor.queue) > 990
    s.command(Stop)
    s.run(0.5 + 2 * s.robot.executor.dt)  # one delay later the stop has been applied
    assert s.robot.executor.state is RobotState.STOPPED
    q = s.robot.executor.q.copy()
    s.run(1.0)
    np.testing.assert_array_equal(s.robot.executor.q, q)
    assert len(s.robot.executor.queue) > 990  # nothing behind it ran


bad_units = st.one_of(
    st.binary(max_size=64),
    st.builds(lambda body: b"TU" + body, st.binary(max_size=64)),
    st.sampled_from(
        [
            encode_unit(1, 0, [], True)[:-1],  # truncated
            encode_unit(1, 0, [Move(joints=(0.0,) * 6)], True)[:12] + b"{bad json",
            encode_unit(1, 0, [Move(joints=(0.0,) * 6)], True).replace(b'"MOVE"', b'"JUMP"'),
            encode_unit(1, 0, [Move(joints=(0.0,) * 6)], True) + b"trailing",
        ]
    ),
)
bad_texts = st.one_of(
    st.text(max_size=64),
    st.sampled_from(['{"type": "explode"}', "[1, 2]", '{"type": "stop"}', "null", '{"type": "hello"}', "x" * 5000]),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.one_of(bad_units, bad_texts), min_size=1, max_size=8))
def test_malformed_input_is_rejected_and_changes_nothing(items) -> None:
    core = RobotCore(Executor(CELL, SimWorld(CELL, CELL.robot, WorldSettings(force_noise=0.0))), session_id="fuzz")
    core.connect()
    core.on_text(encode_message(CommandSender("fuzzer").hello()))
    q = core.executor.q.copy()
    for item in items:
        replies = core.on_unit(item) if isinstance(item, bytes) else core.on_text(item)
        for r in replies:
            json.loads(encode_message(r))  # every reply is a valid message
    for _ in range(3):
        core.tick()
    assert not core.executor.queue and core.executor.current is None
    assert core.receiver.next_number == 1
    np.testing.assert_array_equal(core.executor.q, q)
    assert core.executor.state is RobotState.IDLE


def test_a_rejected_unit_says_why() -> None:
    core = RobotCore(Executor(CELL, SimWorld(CELL, CELL.robot)), session_id="r")
    core.connect()
    core.on_text(encode_message(CommandSender("c").hello()))
    unit = encode_unit(1, 0, [Move(joints=(0.0,) * 6)], True).replace(b'"MOVE"', b'"JUMP"')
    replies = core.on_unit(unit)
    rejected = [r for r in replies if isinstance(r, Rejected)]
    assert rejected and rejected[0].statement_index == 0 and "JUMP" in (rejected[0].detail + (rejected[0].statement or ""))


def test_a_restarted_console_is_told_what_the_robot_holds() -> None:
    s = VirtualSession()
    s.submit(PEG_TRANSFER)
    s.run(s.params.delay_s + 2.0)  # the program arrived and runs
    s.cut()
    s.run(2.0)  # silence: the robot stops and holds its buffer
    s.sender = CommandSender("console-restarted")  # a new console process, knowing nothing
    s.open()
    s.run(2 * s.params.delay_s + 0.1)
    welcome = [m for m in s.received if m.type == "welcome"][-1]
    ex = s.robot.executor
    held = [ex.current[0]] if ex.current is not None else []
    held += [n for n, _ in ex.queue]
    assert held and welcome.holds_total == len(held) and welcome.halted
    assert [h.number for h in welcome.holds] == held
    assert welcome.holds[0].running == (ex.current is not None)
    assert not any(h.running for h in welcome.holds[1:])
    texts = {n: st for n, st in zip(range(1, len(PEG_TRANSFER) + 1), PEG_TRANSFER)}
    for h in welcome.holds:
        assert parse_program(h.text).statements[0] == texts[h.number]  # the text is the statement
        assert h.client_id == "console-test"  # sent by the console before the restart


def test_a_console_that_keeps_its_identity_goes_on_from_the_robots_counters() -> None:
    """A console killed mid-program starts again under the same client id: the robot lists what
    ran (with texts and final states) and what it holds; the new process's first submission,
    made before its welcome, is numbered after the dead one's (never taken for a repeat of its
    communication 1), and a half-sent communication of the dead process is dropped, not spliced."""
    s = VirtualSession(delay=0.5)
    first = s.submit(PEG_TRANSFER[:3])
    s.run_until_final(range(1, 4))
    s.submit(PEG_TRANSFER[3:])
    s.run(s.params.delay_s + 1.0)  # the second communication arrived and runs
    half = encode_unit(3, 0, [Move(joints=(0.0,) * 6)], False)  # the dead process's unfinished third
    s.raw_up(half)
    s.run(s.params.delay_s + 0.1)
    s.cut()  # killed: no goodbye
    s.run(2.0)  # silence: the robot stops and holds
    assert s.robot.executor.halted
    numbered = s.robot.receiver.next_number - 1
    s.sender = CommandSender("console-test", kept_identity=True)  # the same identity, a new process
    late = Move(joints=(0.1,) * 6)
    comm, _units = s.sender.submit([late])  # numbered 1 by the new process before its welcome; not sent before it
    assert first == comm == 1
    s.received.clear()
    s.open()
    s.run(2 * s.params.delay_s + 0.1)
    welcome = next(m for m in s.received if m.type == "welcome")
    assert welcome.units_held == 0 and welcome.last_answered_comm == 2 and welcome.numbered == numbered
    finished = {h.number: h.state for h in welcome.ran}
    assert set(finished) >= {1, 2, 3} and all(state == "done" for state in finished.values())
    assert [h.statement for h in welcome.ran][:3] == PEG_TRANSFER[:3]
    held = {h.number for h in welcome.holds}
    assert held and not held & set(finished) and held | set(finished) == set(range(1, numbered + 1))
    # the replayed answers to the dead process's communications 1 and 2 are not this sender's
    assert s.sender.first_comm == 3 and s.sender.answers == {} and list(s.sender.outbox) == [3]
    s.run(2 * s.params.delay_s + 0.1)
    answers = [m for m in s.received if m.type == "accepted" and m.comm_id == 3]
    assert answers and answers[0].numbers == (numbered + 1,)  # the new statement, numbered after the old ones
    assert s.robot.executor.queue[-1] == (numbered + 1, late)


def test_a_welcome_to_a_robot_with_a_full_buffer_reaches_the_console_whole_or_cut_and_says_so() -> None:
    """5,000 held statements: the welcome stays under what a console takes from its robot, lists
    the held ones first (what a resume runs), and says how many it holds in all."""
    s = VirtualSession(delay=0.1)
    s.command(Stop)
    long_move = Move(joints=(0.123456, -0.654321, 0.5, 0.25, -0.125, 0.0625))
    s.submit([long_move] * s.robot.executor.settings.max_queue)
    s.run(1.0)
    assert len(s.robot.executor.queue) == s.robot.executor.settings.max_queue
    s.cut()
    s.sender = CommandSender("console-other")
    s.received.clear()
    s.open()
    s.run(0.5)
    welcome = next(m for m in s.received if m.type != "rejected")
    assert welcome.type == "welcome" and welcome.holds_total == s.robot.executor.settings.max_queue
    assert [h.number for h in welcome.holds] == list(range(1, len(welcome.holds) + 1))
    assert len(welcome.holds) == welcome.holds_total and welcome.holds[0].statement == long_move
