"""The robot client's telemetry channel (``server.robot_client``): frames taken in the socket's
data callback, kept as the newest, passed through each listener's gate to the listeners' thread.

``TelemetryChannel`` is a part of ``RobotClient`` in a room of its own: it uses the client's
URL, credential headers, silence watch, delivery thread and error count.
"""

from __future__ import annotations

import asyncio
import functools
import logging
from collections.abc import Callable

from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidURI
from websockets.frames import DATA_OPCODES, Frame, Opcode
from websockets.protocol import State

from shared.wire.telemetry import TelemetryError, TelemetryFrame, decode_frame

log = logging.getLogger("teleprog.client")

MAX_MESSAGE_BYTES = 4 << 20


class _TelemetryConnection(ClientConnection):
    """The telemetry socket: each whole binary message goes to ``on_message`` as soon as the
    protocol has parsed it, inside the transport's data callback. ``recv`` is never used on it, so
    a frame costs no queue, no future and no task switch (at 50 Hz on a shared core, about a
    fifth of what reading the socket costs). Text messages are ignored, as the telemetry channel
    always did; pings, pongs and the close go the ordinary way."""

    def __init__(self, protocol, *, on_message: Callable[[bytes], None], **kwargs) -> None:
        super().__init__(protocol, **kwargs)
        self._on_message = on_message
        self._parts: list[bytes] | None = None  # the fragments of a message being received
        self._binary = False
        self._fast = False  # frames split here (``_split``) rather than by the protocol's parser
        self._pending = b""  # the start of a frame not yet whole
        # the protocol's limit on a message (its name in websockets 15 and later; max_size before)
        self._limit = getattr(protocol, "max_message_size", getattr(protocol, "max_size", None))

    def data_received(self, data: bytes) -> None:
        """The socket's bytes. After the handshake they are split into frames here: a whole
        binary message in one frame (what the robot sends 50 times a second) goes straight to
        ``on_message``; every other frame (a ping, a pong, a text, a fragment, the close) is
        handed whole to the protocol, so its parser always stands at a frame's start and does
        what it always did. websockets' own parser is pure Python and cost about a quarter of a
        frame's handling; this split is a few byte reads."""
        if self._fast:
            self._split(self._pending + data if self._pending else data)
            return
        if self.response is not None:
            super().data_received(data)
            return
        end = data.find(b"\r\n\r\n")  # where the handshake's response ends, when it ends here
        if end < 0:
            super().data_received(data)  # a response in pieces: the protocol reads every frame after it
            return
        super().data_received(data[:end + 4])
        if self.response is not None and self.protocol.state is State.OPEN:
            self._fast = True
            self._split(data[end + 4:])
        elif data[end + 4:]:
            super().data_received(data[end + 4:])

    def _split(self, buf: bytes) -> None:
        i, n = 0, len(buf)
        limit = self._limit
        while self._fast and n - i >= 2:
            b0, b1 = buf[i], buf[i + 1]
            length, head = b1 & 0x7F, 2
            if length == 126:
                if n - i < 4:
                    break
                length, head = int.from_bytes(buf[i + 2:i + 4], "big"), 4
            elif length == 127:
                if n - i < 10:
                    break
                length, head = int.from_bytes(buf[i + 2:i + 10], "big"), 10
            if b1 & 0x80:
                head += 4  # a masked frame (a server must not send one): the protocol refuses it
            end = i + head + length
            too_long = limit is not None and length > limit
            if too_long:
                end = n  # not to be waited for: the protocol refuses it from its header
            elif end > n:
                break
            if b0 == 0x82 and not b1 & 0x80 and not too_long:  # FIN, no extension bits, binary, unmasked
                self._on_message(buf[i + head:end])
            else:
                if b0 not in (0x89, 0x8A):  # anything but a ping or a pong: the protocol reads on
                    self._fast = False
                super().data_received(buf[i:end])
            i = end
        rest = buf[i:]
        if self._fast:
            self._pending = rest
        else:
            self._pending = b""
            if rest:
                super().data_received(rest)

    def process_event(self, event) -> None:
        if self.response is None or not isinstance(event, Frame) or event.opcode not in DATA_OPCODES:
            super().process_event(event)  # the handshake's response, control frames
            return
        if event.opcode is not Opcode.CONT:
            self._parts, self._binary = [], event.opcode is Opcode.BINARY
        if self._parts is None:  # a continuation without a start (the protocol refuses those)
            return
        self._parts.append(bytes(event.data))
        if not event.fin:
            return
        parts, self._parts = self._parts, None
        if self._binary:
            self._on_message(parts[0] if len(parts) == 1 else b"".join(parts))


_FAST_TELEMETRY = callable(getattr(ClientConnection, "process_event", None))
"""Whether this websockets has the connection hook ``_TelemetryConnection`` overrides (13 and
later do); without it the telemetry channel reads with ``async for`` as before."""


class TelemetryChannel:
    """The telemetry half of ``RobotClient``."""

    def on_telemetry(self, listener: Callable[[TelemetryFrame], None],
                     gate: Callable[[TelemetryFrame], bool] | None = None) -> None:
        """``listener(frame)`` on the listeners' thread, in arrival order; with ``gate``, only for
        frames ``gate(frame)`` is true for. The gate runs on the loop as each frame arrives: plain
        reads and assignments only (no lock, no I/O); one that raises is counted, the frame passes."""
        self._telemetry_listeners.append((listener, gate))


    # -- the telemetry channel ------------------------------------------------------------------
    async def _telemetry_loop(self) -> None:
        fast = {"create_connection": functools.partial(_TelemetryConnection, on_message=self._telemetry_message)} if _FAST_TELEMETRY else {}
        while not self._closing:
            watchdog: asyncio.Task | None = None
            try:
                async with connect(
                    f"{self.url}/telemetry", max_size=MAX_MESSAGE_BYTES, compression=None, open_timeout=5, close_timeout=1,
                    additional_headers=self._headers, **fast,
                ) as ws:
                    watchdog = asyncio.create_task(self._close_if_silent(ws, self.telemetry_watch, "telemetry"))
                    if fast:
                        await ws.wait_closed()  # the frames go to _telemetry_message as they are parsed
                    else:
                        async for raw in ws:
                            self._telemetry_message(raw)
            except (OSError, ConnectionClosed, InvalidHandshake, asyncio.TimeoutError):
                pass
            except InvalidURI:
                return
            except Exception as exc:  # noqa: BLE001 - last resort: the loop itself must live on
                self._record_error("telemetry channel", exc)
            finally:
                if watchdog is not None:
                    watchdog.cancel()
            await asyncio.sleep(self.reconnect_delay)

    def _telemetry_message(self, raw: str | bytes) -> None:
        """One telemetry message, on the loop (from the connection's data callback): decoded, kept
        as the newest, posted to each listener its gate lets through. Nothing here may raise."""
        self.telemetry_watch.heard(self.now())
        try:
            frame = decode_frame(raw) if isinstance(raw, bytes) else None
        except TelemetryError as exc:
            log.warning("bad telemetry frame: %s", exc)
            return
        except Exception as exc:  # noqa: BLE001 - no frame may end the channel
            self._record_error("handling a telemetry frame", exc)
            return
        if frame is None:  # a text message: not telemetry
            return
        self.telemetry = frame
        self.telemetry_frames += 1
        for listener, gate in self._telemetry_listeners:
            try:
                if gate is not None and not gate(frame):
                    continue
            except Exception as exc:  # noqa: BLE001 - a failing gate lets the frame through
                self._record_error("a telemetry gate", exc)
            self._delivery.post(listener, frame, droppable=True)
