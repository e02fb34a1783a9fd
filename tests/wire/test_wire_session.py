"""The two ends of the command channel under loss and reconnects: exactly-once in effect.

A simulated connection carries the sender's units and messages up and the receiver's replies down;
a cut drops whatever is in flight both ways, as a broken WebSocket would. A toy executor finishes
each accepted statement at once. Whatever the pattern of cuts, every submitted statement must be
taken into the robot's buffer exactly once, in order, and end with exactly one final status.
"""

from __future__ import annotations

from collections import deque

from hypothesis import given, settings
from hypothesis import strategies as st

from shared.language.statements import Drive, Event
from shared.wire.messages import (
    Accepted,
    Rejected,
    RejectReason,
    RobotSnapshot,
    RobotState,
    SkipCurrent,
    StatementState,
    Stop,
    Welcome,
    decode_message,
    encode_message,
)
from shared.wire.session import CommandReceiver, CommandSender
from shared.wire.units import HEADER, encode_unit

SNAP = RobotSnapshot(state=RobotState.IDLE, q=(0.0,) * 6, base_p_tool=(0.4, 0.0, 0.3), tool_rpy=(0.0, 0.0, 0.0))


class Sim:
    """Sender and receiver joined by one connection that can be cut."""

    def __init__(self, per_unit: int = 3) -> None:
        self.sender = CommandSender("console-A", per_unit=per_unit)
        self.receiver = CommandReceiver("robot-1")
        self.buffer: list[tuple[int, object]] = []  # what the robot's buffer received
        self.up: deque = deque()
        self.down: deque = deque()
        self.connected = False
        self.applied: list = []

    def connect(self) -> None:
        self.connected = True
        self.up.append(encode_message(self.sender.hello()))

    def cut(self) -> None:
        self.up.clear()
        self.down.clear()
        self.connected = False
        self.receiver.disconnect()

    def submit(self, statements) -> int:
        comm_id, units = self.sender.submit(statements)
        if self.connected:
            self.up.extend(units)
        return comm_id

    def step_up(self) -> None:
        item = self.up.popleft()
        step = self.receiver.on_unit(item) if isinstance(item, bytes) else self.receiver.on_text(item)
        replies = list(step.replies)
        self.buffer += step.accepted
        for number, _ in step.accepted:  # the toy executor: runs and finishes at once
            replies.append(self.receiver.report(number, StatementState.RUNNING))
            replies.append(self.receiver.report(number, StatementState.DONE, robot=SNAP))
        for cmd in step.recoveries:
            self.applied.append(cmd)
            replies.append(self.receiver.ack(cmd, applied=True))
        self.down.extend(encode_message(r) for r in replies)

    def step_down(self) -> None:
        msg = decode_message(self.down.popleft())
        if isinstance(msg, Welcome):
            for item in self.sender.on_welcome(msg):
                self.up.append(item if isinstance(item, bytes) else encode_message(item))
        else:
            self.sender.on_message(msg)

    def drain(self) -> None:
        while self.up or self.down:
            if self.up:
                self.step_up()
            if self.down:
                self.step_down()


def _program(n: int, base: int) -> list:
    return [Drive(joint=1 + (base + i) % 6, target=(base + i) / 1000.0) for i in range(n)]


@given(
    sizes=st.lists(st.integers(min_value=0, max_value=8), min_size=1, max_size=5),
    actions=st.lists(st.sampled_from(["up", "down", "cut"]), max_size=80),
)
@settings(max_examples=300, deadline=None)
def test_every_statement_is_buffered_once_and_ends_once(sizes, actions):
    sim = Sim()
    sim.connect()
    programs = [_program(n, 100 * k) for k, n in enumerate(sizes)]
    for p in programs:
        sim.submit(p)
    for a in actions:
        if a == "cut":
            sim.cut()
            sim.connect()
        elif a == "up" and sim.up:
            sim.step_up()
        elif a == "down" and sim.down:
            sim.step_down()
    sim.drain()

    expected = [s for p in programs for s in p]
    assert [s for _, s in sim.buffer] == expected  # nothing lost, nothing twice, in order
    numbers = [n for n, _ in sim.buffer]
    assert numbers == list(range(1, len(expected) + 1))
    assert sim.sender.idle
    assert all(isinstance(sim.sender.answers[c], Accepted) for c in range(1, len(programs) + 1))
    got = [n for c in range(1, len(programs) + 1) for n in sim.sender.answers[c].numbers]
    assert got == numbers
    for n in numbers:
        finals = [s for s in sim.sender.statuses[n] if s.final]
        assert finals == [StatementState.DONE]
        assert sim.sender.statuses[n] == [StatementState.RECEIVED, StatementState.RUNNING, StatementState.DONE]


def test_reconnect_resends_only_the_units_the_robot_lacks():
    sim = Sim(per_unit=2)
    sim.connect()
    sim.submit(_program(6, 0))  # three units
    sim.step_up()  # hello
    sim.step_up()  # unit 0
    sim.step_up()  # unit 1
    sim.cut()
    sim.connect()
    sim.step_up()  # hello again
    welcome = decode_message(sim.down[0])
    assert isinstance(welcome, Welcome) and welcome.units_held == 2 and welcome.last_answered_comm == 0
    sim.step_down()
    assert len(sim.up) == 1  # only unit 2 goes again
    sim.drain()
    assert [n for n, _ in sim.buffer] == [1, 2, 3, 4, 5, 6]


def test_answer_lost_on_the_way_back_is_replayed_not_reexecuted():
    sim = Sim()
    sim.connect()
    sim.submit(_program(2, 0))
    sim.step_up()
    sim.step_up()  # accepted, buffered; replies now in flight down
    assert len(sim.buffer) == 2
    sim.cut()  # the answer and the reports are lost
    sim.connect()
    sim.drain()
    assert len(sim.buffer) == 2
    assert sim.sender.answers[1] == Accepted(comm_id=1, numbers=(1, 2))
    assert sim.sender.final_state(1) is StatementState.DONE and sim.sender.final_state(2) is StatementState.DONE


def test_repeated_recovery_commands_apply_once():
    sim = Sim()
    sim.connect()
    sim.drain()
    stop = sim.sender.command(Stop)
    skip = sim.sender.command(SkipCurrent, number=4)
    for _ in range(2):  # the same two commands delivered twice
        sim.up.extend([encode_message(stop), encode_message(skip)])
    sim.drain()
    assert sim.applied == [stop, skip]
    assert sim.sender.idle


def test_unapplied_recovery_command_is_resent_after_reconnect():
    sim = Sim()
    sim.connect()
    sim.drain()
    stop = sim.sender.command(Stop)
    sim.cut()  # the stop never left
    sim.connect()
    sim.drain()
    assert sim.applied == [stop]


def test_malformed_unit_rejects_its_communication_and_changes_nothing_else():
    sim = Sim()
    sim.connect()
    sim.drain()
    bad = HEADER.pack(b"TU", 1, 1, 1, 0, 12) + b'[{"kind":"X"'  # bad JSON, comm 1
    step = sim.receiver.on_unit(bad)
    assert step.accepted == []
    (rej,) = step.replies
    assert isinstance(rej, Rejected) and rej.comm_id == 1 and rej.reason is RejectReason.BAD_JSON
    assert sim.receiver.next_number == 1
    # the next communication is taken normally
    step = sim.receiver.on_unit(encode_unit(2, 0, [Event(name="ok")], end=True))
    assert [n for n, _ in step.accepted] == [1]


def test_bad_statement_in_a_later_unit_is_indexed_across_the_communication():
    receiver = CommandReceiver("r")
    receiver.on_text(encode_message(CommandSender("c").hello()))
    receiver.on_unit(encode_unit(1, 0, _program(3, 0), end=False))
    body = b'[{"kind":"DRIVE","joint":1,"target":0},{"kind":"FLY"}]'
    step = receiver.on_unit(HEADER.pack(b"TU", 1, 1, 1, 1, len(body)) + body)
    (rej,) = step.replies
    assert rej.reason is RejectReason.UNKNOWN_KIND and rej.statement_index == 4 and rej.seq == 1
    assert step.accepted == [] and receiver.next_number == 1


def test_units_before_hello_are_refused():
    receiver = CommandReceiver("r")
    (rej,) = receiver.on_unit(encode_unit(1, 0, [], True)).replies
    assert rej.reason is RejectReason.NO_SESSION


def test_out_of_sequence_units_are_refused():
    receiver = CommandReceiver("r")
    receiver.on_text(encode_message(CommandSender("c").hello()))
    (rej,) = receiver.on_unit(encode_unit(3, 0, [], True)).replies
    assert rej.reason is RejectReason.OUT_OF_SEQUENCE and rej.comm_id == 3
    (rej,) = receiver.on_unit(encode_unit(1, 2, [], True)).replies
    assert rej.reason is RejectReason.OUT_OF_SEQUENCE and rej.comm_id == 1


def test_non_final_rejection_leaves_the_communication_open():
    sim = Sim()
    sim.connect()
    sim.drain()
    comm_id, units = sim.sender.submit(_program(2, 0))
    # a stray unit of a later communication arrives first: refused, but nothing is closed
    early = encode_unit(comm_id + 1, 0, [Event(name="early")], end=True)
    (rej,) = sim.receiver.on_unit(early).replies
    assert isinstance(rej, Rejected) and rej.final is False
    sim.sender.on_message(rej)
    assert comm_id in sim.sender.outbox
    sim.up.extend(units)
    sim.drain()
    assert sim.sender.idle and [n for n, _ in sim.buffer] == [1, 2]


def test_garbage_text_is_refused_without_closing_anything():
    sim = Sim()
    sim.connect()
    sim.drain()
    (rej,) = sim.receiver.on_text("{nonsense").replies
    assert rej.reason is RejectReason.BAD_JSON and rej.final is False
    (rej,) = sim.receiver.on_text(encode_message(Accepted(comm_id=1, numbers=()))).replies
    assert rej.reason is RejectReason.BAD_MESSAGE and rej.final is False
