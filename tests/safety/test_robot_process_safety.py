"""The telerobot's safety contract against the real ``teleprog robot`` process (and the real
``teleprog link`` where the scenario needs it), over real WebSockets on loopback.

The console here is a small synchronous client written for these tests (hello, heartbeats every
0.2 s, units, recovery commands, raw texts), so the robot's side is tested without depending on
the console's client. What is checked: no statement or message ends the process and each gets a
clear answer; stop wins in a run of zero-duration statements, directly and through the link; a
stop far ahead does not lock out later stops; silence (a frozen link, a closed socket) halts the
arm within the limit and resume continues; protocol 2 and client-sent robot messages are refused.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
import uuid

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_program
from shared.language.statements import Event, Move, SetMode, SetSpeed, Speed, SpeedUnit, TaskCall
from shared.wire.messages import (
    CLIENT_TYPES,
    PROTOCOL_VERSION,
    AbortFlush,
    Heartbeat,
    Hello,
    Rejected,
    RejectReason,
    Resume,
    Stop,
    decode_message,
    encode_message,
)
from shared.wire.units import HEADER, UnitHeader, decode_body, encode_unit
from support import LOADED_MACHINE_MARGIN_S, SILENCE_CONTRACT_S, ServerProcess, reported_silence_s, robot_headers, wait_for

CELL = load_cell(DEFAULT_CELL)
SLOW = Speed(value=0.05, unit=SpeedUnit.FRACTION)
LONG_MOVE = Move(joints=tuple(float(v) for v in CELL.q_home + np.radians([60.0, 0, 0, 0, 0, 0])), speed=SLOW)  # ~14 s


class Console:
    """A minimal console on ``/command``: a reader thread keeps every message, a heartbeat
    thread sends one every 0.2 s (``heartbeats=False``: a silent console)."""

    def __init__(
        self, url: str, heartbeats: bool = True, hello: Hello | bool | None = None, client_id: str | None = None,
        reset: bool = True,
    ) -> None:
        self.client_id = client_id or f"safety-{uuid.uuid4().hex[:8]}"
        self.ws = connect(url + "/command", max_size=None, compression=None, open_timeout=10, additional_headers=robot_headers())
        self.messages: list = []
        self.comm = 0
        self.command = 0
        self._lock = threading.Lock()
        self._closed = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        if hello is not False:
            self.send(hello or Hello(client_id=self.client_id))
            self.wait(lambda m: m.type == "welcome", what="welcome")
            if reset and client_id is None:  # a robot shared by the tests: start from idle
                assert self.recover(AbortFlush).applied
        if heartbeats:
            threading.Thread(target=self._beat, daemon=True).start()

    def _read(self) -> None:
        try:
            for raw in self.ws:
                msg = decode_message(raw)
                with self._lock:
                    self.messages.append((time.monotonic(), msg))
        except ConnectionClosed:
            pass
        finally:
            self._closed.set()

    def _beat(self) -> None:
        seq = 0
        while not self._closed.is_set():
            try:
                self.ws.send(encode_message(Heartbeat(seq=seq)))
            except ConnectionClosed:
                return
            seq += 1
            self._closed.wait(0.2)

    # -- sending ------------------------------------------------------------------------------
    def send(self, message) -> None:
        self.ws.send(encode_message(message))

    def submit(self, statements) -> int:
        self.comm += 1
        self.ws.send(encode_unit(self.comm, 0, list(statements), True))
        return self.comm

    def submit_body(self, body: bytes) -> int:
        """One unit with a raw JSON body (whatever a broken or hostile console may send)."""
        self.comm += 1
        self.ws.send(HEADER.pack(b"TU", 1, 1, self.comm, 0, len(body)) + body)
        return self.comm

    def recover(self, kind, command_id: int | None = None, **fields):
        if command_id is None:
            self.command += 1
            command_id = self.command
        self.send(kind(command_id=command_id, **fields))
        return self.wait(lambda m: m.type == "recovery_ack" and m.command_id == command_id, what=f"ack of {command_id}")

    def close(self) -> None:
        self._closed.set()
        self.ws.close()

    # -- reading ------------------------------------------------------------------------------
    def seen(self, predicate) -> list:
        with self._lock:
            return [m for _, m in self.messages if predicate(m)]

    def wait(self, predicate, timeout: float = 15.0, what: str = "message"):
        return wait_for(lambda: (self.seen(predicate) or [None])[-1], timeout=timeout, what=what)

    def answer(self, comm_id: int, timeout: float = 15.0):
        return self.wait(lambda m: m.type in ("accepted", "rejected") and getattr(m, "comm_id", None) == comm_id,
                         timeout=timeout, what=f"answer of communication {comm_id}")


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    """One robot process for the module (it takes seconds to start); each test's console has
    its own client id and begins with an abort, so the robot is idle and unhalted."""
    proc = ServerProcess(tmp_path_factory.mktemp("robot"), "robot", "--seed", "1").start()
    yield proc
    proc.stop()


def alive(robot: ServerProcess) -> dict:
    assert robot.proc.poll() is None, f"the robot exited:\n{robot.log_path.read_text()[-3000:]}"
    health = robot.health()
    assert health["status"] == "ok"
    return health


# -- nothing ends the process ------------------------------------------------------------------------

NASTY_BODIES = [
    b'[{"kind":"DRIVE","joint":1,"target":NaN}]',
    b'[{"kind":"DRIVE","joint":1,"target":1e308}]',
    b'[{"kind":"DRIVE","joint":1,"target":Infinity}]',
    b'[{"kind":"DRIVE","joint":99,"target":0.1}]',
    b'[{"kind":"DRAW","position":[1e6,0,0],"frame":"BASE"}]',
    b'[{"kind":"DRAW","position":[1e308,0,0],"frame":"BASE"}]',
    b'[{"kind":"MOVES","position":[0.4,0,0.3],"rpy":[1e308,NaN,0],"frame":"BASE"}]',
    b'[{"kind":"ROTATE","rpy":[1e300,1e300,1e300],"frame":"TOOL"}]',
    b'[{"kind":"MOVE","joints":[1e308,0,0,0,0,0]}]',
    b'[{"kind":"SPEED","speed":{"value":1e308,"unit":"fraction"}}]',
    b'[{"kind":"EVENT","name":"' + b"x" * 100_000 + b'"}]',
]
NASTY_TEXTS = [
    '{"type":"hello","type":"stop","command_id":1}',
    '{"type":"stop","command_id":NaN}',
    '{"type":"stop","command_id":1e400}',
    "[" * 10_000 + "]" * 10_000,
    '{"type":"skip","command_id":1,"number":-5}',
    "",
]


def test_nasty_statements_and_messages_are_answered_and_the_robot_lives(robot) -> None:
    console = Console(robot.url)
    for body in NASTY_BODIES:
        comm = console.submit_body(body)
        answer = console.answer(comm)
        if answer.type == "accepted":  # taken: it must fail with its reason, not kill the robot
            (number,) = answer.numbers
            report = console.wait(lambda m: m.type == "status" and m.number == number and m.state.final,
                                  what=f"final status of {body[:60]!r}")
            if report.state.value == "failed":
                assert report.reason
                console.recover(Resume)
        else:
            assert answer.detail
        alive(robot)
    for text in NASTY_TEXTS:
        before = len(console.seen(lambda m: m.type == "rejected"))
        console.ws.send(text)
        wait_for(lambda: len(console.seen(lambda m: m.type == "rejected")) > before, what=f"refusal of {text[:40]!r}")
        alive(robot)
    # the repeated-key text did not act as a stop (the robot was idle: a stop would hold it)
    assert alive(robot)["state"] in ("idle", "fault")


numbers = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([1e308, -1e308, 1e-320, 0.0, 3.0e9]),
    st.integers(-(2**70), 2**70),
)
statement_dicts = st.one_of(
    st.fixed_dictionaries({"kind": st.just("DRIVE"), "joint": st.integers(-2, 12), "target": numbers}),
    st.fixed_dictionaries({"kind": st.just("DRAW"), "position": st.lists(numbers, min_size=3, max_size=3),
                           "frame": st.sampled_from(["BASE", "WORK", "TOOL", "WORLD"])}),
    st.fixed_dictionaries({"kind": st.just("MOVES"), "position": st.lists(numbers, min_size=3, max_size=3),
                           "rpy": st.lists(numbers, min_size=3, max_size=3)}),
    st.fixed_dictionaries({"kind": st.just("MOVE"), "joints": st.lists(numbers, min_size=0, max_size=8)}),
    st.fixed_dictionaries({"kind": st.sampled_from(["SPEED", "MODE", "EVENT", "TASK", "FLY"]),
                           "name": st.text(max_size=20)}),
)
raw_texts = st.one_of(
    st.text(max_size=80),
    st.dictionaries(st.sampled_from(["type", "command_id", "client_id", "protocol", "number", "seq"]),
                    st.one_of(numbers, st.text(max_size=10), st.sampled_from(["stop", "hello", "rejected", "status"])),
                    max_size=4).map(json.dumps),
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(items=st.lists(st.one_of(st.lists(statement_dicts, min_size=1, max_size=3), raw_texts), min_size=1, max_size=4))
def test_fuzzed_units_and_texts_never_end_the_robot(robot, items) -> None:
    console = Console(robot.url, heartbeats=False)
    try:
        for item in items:
            if isinstance(item, list):
                body = json.dumps(item).encode()
                comm = console.submit_body(body)
                answer = console.answer(comm)
                # the robot answers as the unit decoder does: accepted with a number per
                # statement, or rejected with the decoder's reason and sentence
                expected = decode_body(UnitHeader(comm_id=comm, seq=0, end=True, body_len=len(body)), body)
                if isinstance(expected, Rejected):
                    assert (answer.type, answer.reason, answer.detail) == ("rejected", expected.reason, expected.detail)
                else:
                    assert answer.type == "accepted" and len(answer.numbers) == len(expected.statements) == len(item)
            else:
                before = len(console.messages)
                console.ws.send(item)
                if decode_message(item, allowed=CLIENT_TYPES).type != "heartbeat":  # taken silently
                    wait_for(lambda: len(console.messages) > before, timeout=10, what=f"an answer to {item[:60]!r}")
        assert console.recover(Stop, command_id=10**6).applied  # a stop is always taken
        alive(robot)
    finally:
        console.close()


# -- stop wins -----------------------------------------------------------------------------------------


def zero_duration(n: int) -> list:
    kinds = [Event(name="mark"), SetSpeed(speed=Speed(value=0.5, unit=SpeedUnit.FRACTION)), SetMode(mode="POSITION"),
             TaskCall(name="release")]
    return [kinds[i % len(kinds)] for i in range(n)]


def _stop_in_a_zero_duration_run(url: str) -> None:
    console = Console(url)
    try:
        answer = console.answer(console.submit(zero_duration(300)))
        assert answer.type == "accepted"
        console.wait(lambda m: m.type == "status" and m.state.value == "running", what="the run to start")
        ack = console.recover(Stop)
        assert ack.applied and ack.robot.state.name == "STOPPED"
        time.sleep(1.0)
        with console._lock:
            order = [m for _, m in console.messages]
        after_ack = order[order.index(ack) + 1 :]
        ours = set(answer.numbers)
        started = [m.number for m in after_ack if m.type == "status" and m.state.value == "running"]
        assert started == [], f"{len(started)} statement(s) started after the stop's acknowledgement"
        done = [m for m in order if m.type == "status" and m.state.value == "done" and m.number in ours]
        assert len(done) < 300  # the stop came in the middle of the run
        ack = console.recover(Resume)
        assert ack.applied
        console.wait(lambda m: m.type == "status" and m.number == answer.numbers[-1] and m.state.final,
                     timeout=20, what="the rest of the run after resume")
    finally:
        console.close()


def test_stop_during_300_zero_duration_statements_starts_nothing_more(robot) -> None:
    _stop_in_a_zero_duration_run(robot.url)


def test_stop_during_300_zero_duration_statements_through_the_link(robot, tmp_path) -> None:
    link = ServerProcess(tmp_path, "link", "--robot", robot.url, "--delay-ms", "300").start()
    try:
        _stop_in_a_zero_duration_run(link.url)
    finally:
        link.stop()


def test_a_stop_far_ahead_does_not_lock_out_smaller_ids(robot) -> None:
    console = Console(robot.url)
    try:
        console.answer(console.submit([LONG_MOVE]))
        console.wait(lambda m: m.type == "status" and m.state.value == "running", what="the move to start")
        assert console.recover(Stop, command_id=1000).applied  # (1 was the opening abort)
        assert alive(robot)["state"] == "stopped"
        assert console.recover(Resume, command_id=2).applied  # the next id is still 2
        wait_for(lambda: robot.health()["state"] == "running", what="running again")
        ack = console.recover(Stop, command_id=3)
        assert ack.applied and ack.robot.state.name == "STOPPED"
        assert robot.health()["state"] == "stopped"
        jump = console.recover(Resume, command_id=50)
        assert not jump.applied and "jumps ahead" in jump.detail
        assert robot.health()["state"] == "stopped"
    finally:
        console.close()


# -- silence halts the arm ---------------------------------------------------------------------------

def test_a_frozen_link_halts_the_robot_within_the_limit_and_resume_continues(robot, tmp_path) -> None:
    link = ServerProcess(tmp_path, "link", "--robot", robot.url, "--delay-ms", "100").start()
    console = Console(link.url)
    try:
        (number,) = console.answer(console.submit([LONG_MOVE])).numbers
        console.wait(lambda m: m.type == "status" and m.state.value == "running", what="the move to start")
        os.kill(link.proc.pid, signal.SIGSTOP)
        try:
            wait_for(lambda: robot.health()["state"] == "stopped", timeout=SILENCE_CONTRACT_S + LOADED_MACHINE_MARGIN_S,
                     interval=0.05, what="robot stopped")
            health = robot.health()
            assert health["halted"].startswith("no message from the console for")
            # on the robot's own servo clock: halted at the contract's 1.2 s of silence (0.1 s steps)
            assert reported_silence_s(health["halted"]) == pytest.approx(SILENCE_CONTRACT_S, abs=0.05), health["halted"]
            q = telemetry_q(robot)
            time.sleep(0.5)
            np.testing.assert_allclose(telemetry_q(robot), q, atol=2e-4)  # holding (a braked physical arm settles by ~1e-5 rad)
        finally:
            os.kill(link.proc.pid, signal.SIGCONT)
        halted = console.wait(lambda m: m.type == "halted", what="the halt to reach the console")
        assert halted.cause.value == "silence" and "limit 1.0 s beyond the 0.2 s heartbeat" in halted.detail
        assert console.recover(Resume).applied
        wait_for(lambda: robot.health()["state"] == "running", what="running after resume")
        assert robot.health()["halted"] is None
        assert console.seen(lambda m: m.type == "status" and m.number == number and m.state.final) == []
    finally:
        console.close()
        link.stop()


def test_closing_the_socket_mid_motion_stops_the_robot_within_the_limit(robot) -> None:
    console = Console(robot.url)
    console.answer(console.submit([LONG_MOVE, Event(name="after")]))
    console.wait(lambda m: m.type == "status" and m.state.value == "running", what="the move to start")
    console.close()
    wait_for(lambda: robot.health()["state"] == "stopped", timeout=SILENCE_CONTRACT_S + LOADED_MACHINE_MARGIN_S,
             interval=0.05, what="robot stopped")
    # on the robot's own servo clock: halted at the contract's 1.2 s of silence (0.1 s steps)
    assert reported_silence_s(robot.health()["halted"]) == pytest.approx(SILENCE_CONTRACT_S, abs=0.05)
    # the next console hears why in its welcome, and the robot holds until it resumes
    again = Console(robot.url, client_id=console.client_id)
    try:
        welcome = again.seen(lambda m: m.type == "welcome")[0]
        assert welcome.halted and welcome.halted.startswith("no message from the console")
        assert again.wait(lambda m: m.type == "halted", what="the halt, kept for the next console").cause.value == "silence"
        time.sleep(0.3)
        assert robot.health()["state"] == "stopped"
        assert again.recover(Resume, command_id=console.command + 1).applied
        wait_for(lambda: robot.health()["state"] == "running", what="running after resume")
    finally:
        again.close()


def test_an_idle_robot_keeps_serving_a_quiet_console(robot) -> None:
    console = Console(robot.url, heartbeats=False)
    try:
        time.sleep(1.6)  # silent past the limit, but nothing to stop
        assert alive(robot)["state"] == "idle" and robot.health()["halted"] is None
        console.answer(console.submit([Event(name="later")]))
        console.wait(lambda m: m.type == "status" and m.state.value == "done", what="the event to run")
        assert console.seen(lambda m: m.type == "heartbeat")  # the robot's own heartbeats flow
    finally:
        console.close()


def telemetry_q(robot: ServerProcess) -> tuple:
    from shared.wire.telemetry import decode_frame

    with connect(robot.url + "/telemetry", open_timeout=10, additional_headers=robot_headers()) as ws:
        return decode_frame(ws.recv(timeout=5)).q


# -- protocol and message types --------------------------------------------------------------------


def test_protocol_2_and_client_sent_robot_messages_are_refused(robot) -> None:
    console = Console(robot.url, heartbeats=False, hello=False)
    try:
        console.send(Hello(client_id=console.client_id, protocol=PROTOCOL_VERSION + 1))
        rej = console.wait(lambda m: m.type == "rejected", what="refusal of protocol 2")
        assert rej.reason is RejectReason.PROTOCOL and not rej.final
        assert rej.detail == f"protocol {PROTOCOL_VERSION + 1} not supported; this robot speaks {PROTOCOL_VERSION}"
        assert console.seen(lambda m: m.type == "welcome") == []
        console.send(Hello(client_id=console.client_id))
        console.wait(lambda m: m.type == "welcome", what="welcome")
        console.send(Rejected(comm_id=1, reason=RejectReason.BUFFER_FULL, detail="forged by a client"))
        rej = console.wait(lambda m: m.type == "rejected" and m.reason is RejectReason.BAD_MESSAGE, what="refusal")
        assert "forged" not in rej.detail and "'rejected'" in rej.detail
        alive(robot)
    finally:
        console.close()


# -- recovery from contact (finding 13) -----------------------------------------------------------------


def test_after_a_contact_fault_the_arm_backs_away_and_cannot_press_further(robot) -> None:
    console = Console(robot.url)
    try:
        into = parse_program(
            "MOVES TO (0, -30, 120) mm (180, 0, 0) deg IN WORK\nDRAW TO (0, -30, -20) mm IN WORK"  # gripper into plate
        ).statements
        first, second = console.answer(console.submit(into)).numbers
        report = final_of(console, second, timeout=60)
        assert report.state.value == "failed" and "unplanned contact" in report.reason
        assert console.recover(Resume).applied
        (down,) = console.answer(console.submit(parse_program("DRAW TO (0, -30, -30) mm IN WORK").statements)).numbers
        assert final_of(console, down).state.value == "failed"
        assert console.recover(Resume).applied
        (up,) = console.answer(console.submit(parse_program("DRAW TO (0, -30, 120) mm IN WORK").statements)).numbers
        report = final_of(console, up, timeout=60)
        assert report.state.value == "done", report.reason
        assert alive(robot)["state"] == "idle"
    finally:
        console.close()


def final_of(console: Console, number: int, timeout: float = 30.0):
    return console.wait(lambda m: m.type == "status" and m.number == number and m.state.final, timeout=timeout,
                        what=f"final status of statement {number}")
