"""The console's telemetry path (issue 35): what each frame costs is its decoding and a gate on
the robot client's loop; the session's listeners see a frame only when it matters.

* the real ``RobotClient`` against a scripted robot on loopback: every binary message is decoded
  and counted, its gate asked on the client's loop, and only the frames the gate lets through
  reach the listener (in order); text messages are ignored and a fragmented frame is put back
  together, as with ``recv``; a gate that raises is counted and lets its frame through;
* the remote mirror's gate (``RemoteMirror.gate_frame``): the newest frame is kept at once,
  whatever the gate answers; it lets through a change of robot state, the frame that makes the
  remote arm's publication due, and every frame while ``bus.telemetry`` has a listener.
"""

from __future__ import annotations

import asyncio
import threading

import pytest
from websockets.asyncio.server import serve

from server.robot_client import RobotClient
from shared.wire.messages import ControlMode, RobotState, Welcome, decode_message, encode_message
from shared.wire.telemetry import TelemetryFrame, encode_frame
from support import free_port


def _frame(n: int, state: RobotState = RobotState.IDLE, q0: float = 0.0) -> TelemetryFrame:
    return TelemetryFrame(time=0.02 * n, frame=n, state=state, mode=ControlMode.POSITION, statement=0,
                          q=(q0, -0.5, 0.5, 0.0, 0.3, 0.0), position=(0.4, 0.0, 0.3), rpy=(0.0, 3.1, 0.0))


class TelemetryRobot:
    """Welcomes the client on /command; on /telemetry sends ``messages`` (bytes, str, or a list
    of byte fragments for one fragmented message) once the test says go."""

    def __init__(self, messages: list) -> None:
        self.port = free_port()
        self.messages = messages
        self.go = asyncio.Event()

    async def handle(self, ws) -> None:
        if ws.request.path == "/telemetry":
            await self.go.wait()
            for message in self.messages:
                await ws.send(message)
            await ws.wait_closed()
            return
        async for raw in ws:
            if isinstance(raw, str) and decode_message(raw).type == "hello":
                await ws.send(encode_message(Welcome(session_id="scripted", last_answered_comm=0, units_held=0,
                                                     last_applied_command=0, last_report_seq=0)))


def _run_client(messages: list, gate) -> tuple[list[TelemetryFrame], RobotClient, set[str]]:
    """Frames the listener got, the client (closed) and the names of the threads the gate ran on."""
    delivered: list[TelemetryFrame] = []
    done = threading.Event()
    gate_threads: set[str] = set()
    expected = sum(1 for m in messages if not isinstance(m, str))

    def counting_gate(frame: TelemetryFrame) -> bool:
        gate_threads.add(threading.current_thread().name)
        return gate(frame)

    def listener(frame: TelemetryFrame) -> None:
        delivered.append(frame)
        if frame.frame == expected:  # the last frame of every test is let through
            done.set()

    async def run() -> RobotClient:
        robot = TelemetryRobot(messages)
        async with serve(robot.handle, "127.0.0.1", robot.port):
            async with RobotClient(f"ws://127.0.0.1:{robot.port}") as client:
                client.on_telemetry(listener, gate=counting_gate if gate is not None else None)
                robot.go.set()
                assert await asyncio.to_thread(done.wait, 10.0), "the last frame never reached the listener"
                return client

    return delivered, asyncio.run(run()), gate_threads


def test_the_client_asks_the_gate_for_every_frame_and_delivers_only_what_it_lets_through() -> None:
    frames = [_frame(n) for n in range(1, 11)]
    data = [encode_frame(f) for f in frames]
    fragmented = [data[4][:50], data[4][50:120], data[4][120:]]
    messages = [*data[:4], "not telemetry", fragmented, *data[5:]]
    asked: list[int] = []

    def gate(frame: TelemetryFrame) -> bool:
        asked.append(frame.frame)
        return frame.frame % 3 == 1 or frame.frame == 10

    delivered, client, threads = _run_client(messages, gate)
    assert asked == list(range(1, 11))  # every frame, the fragmented one too, none twice, the text ignored
    assert [f.frame for f in delivered] == [1, 4, 7, 10]
    assert delivered == [frames[i - 1] for i in (1, 4, 7, 10)]  # decoded to the same frames
    assert threads == {threading.main_thread().name}  # the client's loop, not the listeners' thread
    h = client.health()
    assert h.telemetry_frames == 10 and client.telemetry == frames[-1] and h.errors == 0


def test_a_gate_that_raises_is_counted_and_lets_the_frame_through() -> None:
    def gate(frame: TelemetryFrame) -> bool:
        if frame.frame == 2:
            raise ZeroDivisionError("a broken gate")
        return frame.frame == 3

    delivered, client, _ = _run_client([encode_frame(_frame(n)) for n in (1, 2, 3)], gate)
    assert [f.frame for f in delivered] == [2, 3]
    assert client.health().errors == 1 and "ZeroDivisionError" in (client.health().last_error or "")


def test_without_a_gate_every_frame_reaches_the_listener() -> None:
    delivered, client, _ = _run_client([encode_frame(_frame(n)) for n in range(1, 6)], None)
    assert [f.frame for f in delivered] == [1, 2, 3, 4, 5] and client.health().telemetry_frames == 5


# -- the remote mirror's gate --------------------------------------------------------------------
def test_the_mirror_keeps_every_frame_and_lets_through_only_changes_and_due_publications(session, clock) -> None:
    mirror = session.remote
    period = 1.0 / session.settings.remote_event_hz
    assert mirror.gate_frame(_frame(1))  # the first frame: a state to take
    mirror.take_frame(_frame(1))
    for n in range(2, 5):  # 20 ms apart, within the publication period, same state
        clock.advance(0.02)
        assert not mirror.gate_frame(_frame(n, q0=0.01 * n))
        assert mirror.telemetry == _frame(n, q0=0.01 * n) and mirror.telemetry_at == clock()  # the newest, always
        assert session.link.telemetry_age_s() == 0.0  # the remote arm's age: from the newest frame
    remote = session.remote.view()
    assert remote is not None and remote.q[0] == pytest.approx(0.04)  # the API's view shows the newest frame
    clock.advance(period - 0.06 + 1e-9)  # 0.1 s after the first frame's publication
    assert mirror.gate_frame(_frame(5))  # the publication is due
    mirror.take_frame(_frame(5))
    clock.advance(0.02)
    assert mirror.gate_frame(_frame(6, RobotState.RUNNING))  # a state change: at once
    mirror.take_frame(_frame(6, RobotState.RUNNING))
    clock.advance(0.02)
    assert not mirror.gate_frame(_frame(7, RobotState.RUNNING))
    seen: list[int] = []
    remove = session.bus.telemetry.add(lambda frame: seen.append(frame.frame))
    clock.advance(0.02)
    assert mirror.gate_frame(_frame(8, RobotState.RUNNING))  # someone records every frame
    mirror.take_frame(_frame(8, RobotState.RUNNING))
    assert seen == [8]
    remove()
    clock.advance(0.02)
    assert not mirror.gate_frame(_frame(9, RobotState.RUNNING))


def test_publications_from_gated_frames_show_the_newest_frame(session, clock) -> None:
    from server.console import RemoteArmChanged

    published: list = []
    session.subscribe_events(lambda e: published.append(e.remote) if isinstance(e, RemoteArmChanged) else None)
    mirror = session.remote
    period = 1.0 / session.settings.remote_event_hz
    expected, emitted_at = [], float("-inf")  # what the mirror published for each frame before the gate
    for n in range(1, 26):  # half a second at 50 Hz, idle
        if n == 1 or clock() - emitted_at >= period:
            expected.append(n)
            emitted_at = clock()
        if mirror.gate_frame(_frame(n, q0=0.001 * n)):
            mirror.take_frame(_frame(n, q0=0.001 * n))
        clock.advance(0.02)
    # the same publications as every frame taken: the first, then each due one, from that frame
    assert [round(v.q[0] * 1000) for v in published] == expected and len(expected) >= 4
    assert all(v.state == "idle" for v in published)


# -- the telemetry socket's own frame split ------------------------------------------------------


class _Transport:
    """What the connection writes (a pong, a close) and nothing else of a socket."""

    def __init__(self) -> None:
        self.written = bytearray()
        self.closed = False

    def write(self, data: bytes) -> None:
        self.written += data

    def is_closing(self) -> bool:
        return self.closed

    def close(self) -> None:
        self.closed = True

    abort = close

    def get_extra_info(self, name, default=None):
        return default

    def set_write_buffer_limits(self, high=None, low=None) -> None:
        pass

    def get_write_buffer_size(self) -> int:
        return 0

    def pause_reading(self) -> None:
        pass

    def resume_reading(self) -> None:
        pass


def _split_run(stream_of, cuts: list[int], max_size: int = 1 << 16) -> tuple[list[bytes], _Transport, object]:
    """Feed a telemetry connection the handshake's response and ``stream_of(response)`` cut at
    ``cuts``; the messages it handed on, its transport and the connection."""
    from websockets.client import ClientProtocol
    from websockets.uri import parse_uri
    from websockets.utils import accept_key

    from server.robot_telemetry import _TelemetryConnection

    async def run():
        protocol = ClientProtocol(parse_uri("ws://127.0.0.1:1/telemetry"), max_size=max_size)
        got: list[bytes] = []
        conn = _TelemetryConnection(protocol, on_message=got.append, ping_interval=None)
        transport = _Transport()
        conn.connection_made(transport)
        request = protocol.connect()
        protocol.send_request(request)
        response = (b"HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                    b"Sec-WebSocket-Accept: " + accept_key(request.headers["Sec-WebSocket-Key"]).encode() + b"\r\n\r\n")
        stream = response + stream_of()
        edges = sorted({0, len(stream), *(c % (len(stream) + 1) for c in cuts)})
        for a, b in zip(edges, edges[1:]):
            conn.data_received(stream[a:b])
        return got, transport, conn

    return asyncio.run(run())


def _wire(opcode, payload: bytes, fin: bool = True) -> bytes:
    from websockets.frames import Frame
    return Frame(opcode, payload, fin=fin).serialize(mask=False)


@pytest.mark.parametrize("cuts", [[], [1], [130, 131, 132], [7, 19, 250, 251, 600, 2000], list(range(0, 3000, 37))])
def test_frames_split_by_the_connection_are_the_messages_sent_however_the_bytes_arrive(cuts) -> None:
    """Binary messages in every length encoding, a ping between them (answered), arriving with
    the handshake's response, one byte at a time or many frames in one read: each message is
    handed on once, whole, in order, as the protocol's own parser hands them."""
    from websockets.frames import Opcode

    messages = [encode_frame(_frame(n)) for n in range(1, 5)] + [bytes(range(256)) * 2, b"x" * 70_000, b""]
    stream = lambda: (_wire(Opcode.BINARY, messages[0]) + _wire(Opcode.PING, b"still there?")  # noqa: E731
                      + b"".join(_wire(Opcode.BINARY, m) for m in messages[1:]))
    got, transport, conn = _split_run(stream, cuts, max_size=1 << 20)
    assert [bytes(m) for m in got] == messages
    sent = bytes(transport.written).split(b"\r\n\r\n", 1)[1]  # after the handshake's request
    assert sent[:2] == b"\x8a\x8c"  # the ping was answered by the protocol: a pong of its 12 bytes (masked)
    assert conn._fast and conn._pending == b""  # noqa: SLF001 - still splitting, nothing left over


def test_a_frame_the_split_does_not_take_goes_to_the_protocol_and_it_reads_on() -> None:
    """A text message, a fragmented binary message and a frame over the size limit: the protocol
    gets each whole and from then on reads the socket itself, as it always did."""
    from websockets.frames import Opcode

    first, later = encode_frame(_frame(1)), encode_frame(_frame(2))
    stream = lambda: (_wire(Opcode.BINARY, first) + _wire(Opcode.TEXT, b"not telemetry")  # noqa: E731
                      + _wire(Opcode.BINARY, later[:40], fin=False) + _wire(Opcode.CONT, later[40:]))
    got, _, conn = _split_run(stream, [3, 200])
    assert [bytes(m) for m in got] == [first, later] and not conn._fast  # noqa: SLF001
    too_big = lambda: _wire(Opcode.BINARY, first) + _wire(Opcode.BINARY, b"y" * 5000)  # noqa: E731
    got, transport, conn = _split_run(too_big, [], max_size=4096)
    assert [bytes(m) for m in got] == [first]  # the long one is refused, never handed on in part
    sent = bytes(transport.written).split(b"\r\n\r\n", 1)[1]
    assert sent[:1] == b"\x88" and not conn._fast  # noqa: SLF001 - the protocol closes: the message is too big
