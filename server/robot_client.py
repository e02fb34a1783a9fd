"""A typed asyncio client of the telerobot, straight or through the delayed link.

Used by the console, by headless trials and by the tests::

    async with RobotClient("ws://127.0.0.1:8765") as robot:
        numbers = await robot.submit(program)          # waits for the robot's answer
        finals = await robot.wait_final(numbers)       # number -> final StatusReport
        frame = robot.telemetry                        # newest TelemetryFrame, or None

Both channels reconnect by themselves. After a reconnect the command channel runs the
``hello``/``welcome`` handshake of ``shared.wire.messages`` and sends again only what the robot
lacks, so a cut link loses nothing and runs nothing twice. All bookkeeping (numbering, what to
resend, which reports are new) is the sans-I/O ``CommandSender``; this class only moves bytes.

What keeps the channels honest (``health()`` says it all at once):

* no message ends a channel: an error while decoding or handling one, or in a report or
  telemetry listener, is logged with its traceback, counted (``errors``, ``last_error``) and the
  loop goes on;
* the loop only moves bytes: listeners run on a thread of their own, in arrival order
  (``server.delivery``), so a slow or blocked listener never delays a heartbeat or a STOP;
* telemetry costs the loop one decode a frame (``decode_frame``) and, per telemetry listener
  registered with a ``gate``, one call of that gate; a frame reaches such a listener only when
  its gate says so (the console's remote mirror wants a frame when it changes the robot's state,
  when its 10 Hz publication is due, or every frame while something records them), so 50 frames
  a second do not mean 50 wakes of the listeners' thread;
* liveness: once greeted the client sends a ``Heartbeat`` every ``HEARTBEAT_INTERVAL_S`` through
  the same writer as units; a ``SilenceWatch`` per channel (event-loop monotonic time) calls the
  command channel *silent* and telemetry *stale* past the silence limit, and a socket that stays
  open but silent for ``reconnect_silence_s`` is closed and opened again;
* ``Halted`` (the robot stopped by itself) is kept in ``halted`` until a resume, skip or abort is
  acknowledged as applied (``Welcome.halted`` sets or clears it too);
* a welcome from another robot session (the robot restarted) fails every waiting submission,
  command and final with ``RobotRestarted``: their fate is unknown, and nothing of the old session
  is sent to the new robot.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import time
import uuid
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from pydantic import BaseModel
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidURI
from websockets.frames import DATA_OPCODES, Frame, Opcode

from server.delivery import Delivery
from shared.errors import TeleprogError
from shared.startup_trace import mark
from shared.language.statements import Statement
from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S, HEARTBEAT_INTERVAL_S, SilenceWatch
from shared.wire.messages import (
    ROBOT_TYPES,
    AbortFlush,
    Accepted,
    Halted,
    Heartbeat,
    Recovery,
    RecoveryAck,
    Rejected,
    RejectReason,
    Resume,
    SkipCurrent,
    StatusReport,
    Stop,
    Welcome,
    decode_message,
    encode_message,
)
from shared.wire.session import CommandSender, SessionRestart
from shared.wire.telemetry import FRAME_RATE_HZ, TelemetryError, TelemetryFrame, decode_frame

log = logging.getLogger("teleprog.client")

MAX_MESSAGE_BYTES = 4 << 20
RECONNECT_SILENCE_FACTOR = 10.0
"""An open socket silent for this many silence limits is closed and opened again."""


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


class CommunicationRejected(TeleprogError):
    """The robot refused a whole communication; ``answer`` says why and where."""

    def __init__(self, answer: Rejected, statements: int | None = None) -> None:
        self.answer = answer
        if answer.reason is RejectReason.BUFFER_FULL:
            held = f"{statements} statements" if statements is not None else "the communication"
            super().__init__(f"robot buffer full: {held} held back (communication {answer.comm_id}: {answer.detail})")
            return
        where = f" at statement {answer.statement_index + 1}" if answer.statement_index is not None else ""
        super().__init__(f"robot rejected communication {answer.comm_id}{where}: {answer.reason.value}: {answer.detail}")


class RobotRestarted(TeleprogError):
    """The robot answered with a new session: what the old one left unanswered is unknown."""

    def __init__(self, restart: SessionRestart) -> None:
        self.restart = restart
        super().__init__(restart.describe())


@dataclass(frozen=True)
class ChannelHealth:
    """The two channels as the client sees them now (ages in seconds)."""

    connected: bool
    command: str
    """``down`` (no socket), ``connecting`` (socket open, no welcome yet), ``live`` or ``silent``."""
    heard_ago_s: float | None
    """Since anything last arrived on the command channel (None: nothing on this connection)."""
    silence_limit_s: float
    telemetry: str
    """``none`` (no frame yet), ``live`` or ``stale``."""
    telemetry_ago_s: float | None
    halted: str | None
    errors: int
    last_error: str | None
    refused: str | None
    buffer_full: str | None
    session_id: str | None
    restarts: int
    telemetry_frames: int = 0
    """Telemetry frames received and decoded since the client started (every connection)."""


class RobotClient:
    """Command and telemetry channels of one robot, with reconnects and exactly-once submission."""

    def __init__(
        self,
        url: str,
        client_id: str | None = None,
        reconnect_delay: float = 0.2,
        silence_limit_s: float = DEFAULT_SILENCE_LIMIT_S,
        reconnect_silence_s: float | None = None,
    ) -> None:
        self.url = url.rstrip("/")
        self.sender = CommandSender(client_id or f"console-{uuid.uuid4().hex[:12]}")
        self.reconnect_delay = reconnect_delay
        self.telemetry: TelemetryFrame | None = None
        self.reports: list[StatusReport] = []
        self.connected = asyncio.Event()
        self.reconnects = 0
        self.handshake_s: float | None = None
        """Seconds from ``hello`` to ``welcome`` on the newest connection: one round trip over
        the link, without the time spent waiting for the robot or link to come up."""
        self.command_watch = SilenceWatch(HEARTBEAT_INTERVAL_S, silence_limit_s)
        self.telemetry_watch = SilenceWatch(1.0 / FRAME_RATE_HZ, silence_limit_s)
        self.reconnect_silence_s = reconnect_silence_s or RECONNECT_SILENCE_FACTOR * silence_limit_s
        self.errors = 0
        self.last_error: str | None = None
        self.halted: str | None = None
        self.refused: str | None = None
        self.buffer_full: str | None = None
        self.restarts: list[SessionRestart] = []
        self.heartbeats_heard = 0
        """Heartbeats the robot sent (a robot that sends none is judged by its other messages)."""
        self._ws: ClientConnection | None = None
        self._lock = asyncio.Lock()  # one writer: welcome replays, heartbeats and new units never interleave
        self._answers: dict[int, asyncio.Future[Accepted | Rejected]] = {}
        self._acks: dict[int, asyncio.Future[RecoveryAck]] = {}
        self._finals: dict[int, asyncio.Future[StatusReport]] = {}
        self._report_listeners: list[Callable[[StatusReport], None]] = []
        self._telemetry_listeners: list[tuple[Callable[[TelemetryFrame], None], Callable[[TelemetryFrame], bool] | None]] = []
        self.telemetry_frames = 0  # received and decoded, every connection
        self._restart_listeners: list[Callable[[SessionRestart], None]] = []
        self._tasks: list[asyncio.Task] = []
        self._closing = False
        self._loop: asyncio.AbstractEventLoop | None = None
        self._delivery = Delivery(name=f"robot-listeners {self.url}", on_error=lambda where, exc: self._record_error(
            f"a listener ({where})", exc))
        """Reports, telemetry and restarts reach the listeners on this thread, never on the loop
        (``server.delivery``): nothing a listener does can starve the heartbeats."""

    # -- lifecycle ------------------------------------------------------------------------------
    async def __aenter__(self) -> RobotClient:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def start(self, timeout: float = 10.0) -> None:
        """Open both channels; returns once the command channel has its welcome."""
        self._loop = asyncio.get_running_loop()
        self._tasks = [asyncio.create_task(self._command_loop()), asyncio.create_task(self._telemetry_loop())]
        try:
            await asyncio.wait_for(self.connected.wait(), timeout)
        except asyncio.TimeoutError:
            await self.close()
            raise TeleprogError(f"no answer from the robot at {self.url} within {timeout:g} s") from None

    async def close(self) -> None:
        self._closing = True
        for t in self._tasks:
            t.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        self._tasks = []
        self._delivery.close()

    def on_report(self, listener: Callable[[StatusReport], None]) -> None:
        self._report_listeners.append(listener)

    def on_telemetry(self, listener: Callable[[TelemetryFrame], None],
                     gate: Callable[[TelemetryFrame], bool] | None = None) -> None:
        """``listener(frame)`` on the listeners' thread, in arrival order; with ``gate``, only for
        frames ``gate(frame)`` is true for. The gate runs on the loop as each frame arrives: plain
        reads and assignments only (no lock, no I/O); one that raises is counted, the frame passes."""
        self._telemetry_listeners.append((listener, gate))

    def on_restart(self, listener: Callable[[SessionRestart], None]) -> None:
        """``listener(restart)`` runs when a welcome comes from a new robot session."""
        self._restart_listeners.append(listener)

    # -- health ---------------------------------------------------------------------------------
    def now(self) -> float:
        """The event loop's monotonic clock (the one the silence watches run on)."""
        return self._loop.time() if self._loop is not None else time.monotonic()

    def health(self) -> ChannelHealth:
        """Both channels now; safe to call from any thread (it only reads)."""
        now = self.now()
        connected = self.connected.is_set()
        if connected:
            command = "silent" if self.command_watch.silent(now) else "live"
        else:
            command = "connecting" if self._ws is not None else "down"
        tele = self.telemetry_watch
        telemetry = "none" if not tele.armed else ("stale" if tele.silent(now) else "live")
        return ChannelHealth(
            connected=connected, command=command, heard_ago_s=self.command_watch.age(now),
            silence_limit_s=self.command_watch.limit, telemetry=telemetry, telemetry_ago_s=tele.age(now),
            halted=self.halted, errors=self.errors, last_error=self.last_error, refused=self.refused,
            buffer_full=self.buffer_full, session_id=self.sender.session_id, restarts=len(self.restarts),
            telemetry_frames=self.telemetry_frames,
        )

    def _record_error(self, where: str, exc: BaseException) -> None:
        """An error inside a channel's handling: logged with its traceback, counted, kept."""
        self.errors += 1
        self.last_error = f"{where}: {type(exc).__name__}: {exc}"[:500]
        log.error("%s failed (the channel carries on)", where, exc_info=exc)

    # -- commands -------------------------------------------------------------------------------
    async def submit(self, statements: Iterable[Statement], timeout: float | None = None) -> tuple[int, ...]:
        """Send a communication; return the numbers the robot gave its statements.

        Raises ``CommunicationRejected`` when the robot refuses it and ``RobotRestarted`` when
        the robot restarts before answering. The communication is kept and resent across
        reconnects until answered, so waiting survives a cut link.
        """
        statements = list(statements)
        async with self._lock:
            comm_id, units = self.sender.submit(statements)
            future = self._answers.setdefault(comm_id, asyncio.get_running_loop().create_future())
            if self._ws is not None and self.connected.is_set():
                await self._send_all(units)
        answer = await asyncio.wait_for(asyncio.shield(future), timeout)
        if isinstance(answer, Rejected):
            raise CommunicationRejected(answer, len(statements))
        return answer.numbers

    async def stop(self, timeout: float | None = None) -> RecoveryAck:
        return await self._recover(Stop, timeout)

    async def resume(self, timeout: float | None = None) -> RecoveryAck:
        return await self._recover(Resume, timeout)

    async def skip(self, number: int, timeout: float | None = None) -> RecoveryAck:
        return await self._recover(SkipCurrent, timeout, number=number)

    async def abort(self, timeout: float | None = None) -> RecoveryAck:
        return await self._recover(AbortFlush, timeout)

    async def _recover(self, kind: type[Recovery], timeout: float | None, **fields: object) -> RecoveryAck:
        async with self._lock:
            cmd = self.sender.command(kind, **fields)  # ids increase by one: the robot refuses jumps
            future = self._acks.setdefault(cmd.command_id, asyncio.get_running_loop().create_future())
            if self._ws is not None and self.connected.is_set():
                await self._send_all([cmd])
        return await asyncio.wait_for(asyncio.shield(future), timeout)

    async def wait_final(self, numbers: Iterable[int], timeout: float | None = None) -> dict[int, StatusReport]:
        """Wait until every numbered statement has its final status report (``RobotRestarted``
        when the robot restarts first)."""
        futures = {n: self._final_future(n) for n in numbers}
        await asyncio.wait_for(asyncio.gather(*futures.values()), timeout)
        return {n: f.result() for n, f in futures.items()}

    def _final_future(self, number: int) -> asyncio.Future[StatusReport]:
        if number not in self._finals:
            self._finals[number] = asyncio.get_running_loop().create_future()
        return self._finals[number]

    # -- the command channel --------------------------------------------------------------------
    async def _send_all(self, items: list[bytes | BaseModel]) -> None:
        """Send on the open socket. A socket that closes under the send is not the caller's
        failure: what was not answered stays with the sender and goes out again after the next
        welcome, so a submission or command survives a link that drops while it is sent."""
        assert self._ws is not None
        try:
            for item in items:
                await self._ws.send(item if isinstance(item, bytes) else encode_message(item))
        except ConnectionClosed as exc:
            log.info("the command channel closed while sending (%s); resent after the next welcome", exc)

    async def _command_loop(self) -> None:
        said_down = False  # one line per outage, not one per retry
        while not self._closing:
            helpers: list[asyncio.Task] = []
            try:
                async with connect(
                    f"{self.url}/command", max_size=MAX_MESSAGE_BYTES, compression=None, open_timeout=5, close_timeout=1
                ) as ws:
                    self._ws = ws
                    self.command_watch.reset()
                    hello_at = time.monotonic()
                    await ws.send(encode_message(self.sender.hello()))
                    mark("console", "hello sent")
                    helpers = [
                        asyncio.create_task(self._heartbeats(ws)),
                        asyncio.create_task(self._close_if_silent(ws, self.command_watch, "command channel")),
                    ]
                    async for raw in ws:
                        self.command_watch.heard(self.now())
                        try:
                            await self._take(raw, hello_at)
                        except ConnectionClosed:
                            raise
                        except Exception as exc:  # noqa: BLE001 - no message may end the channel
                            self._record_error("handling a message from the robot", exc)
                    said_down = False
            except (OSError, ConnectionClosed, InvalidHandshake, asyncio.TimeoutError) as exc:
                if not self._closing and not said_down:
                    log.info("command channel to %s down: %s (retrying quietly)", self.url, exc or type(exc).__name__)
                    said_down = True
                elif not self._closing:
                    log.debug("command channel to %s still down: %s", self.url, exc or type(exc).__name__)
            except InvalidURI as exc:
                log.error("bad robot URL %s: %s", self.url, exc)
                return
            except Exception as exc:  # noqa: BLE001 - last resort: the loop itself must live on
                self._record_error("command channel", exc)
            finally:
                for task in helpers:
                    task.cancel()
                self._ws = None
                if self.connected.is_set():
                    self.reconnects += 1
                    said_down = False
                self.connected.clear()
            await asyncio.sleep(self.reconnect_delay)

    async def _take(self, raw: str | bytes, hello_at: float) -> None:
        """One message from the robot."""
        msg = decode_message(raw, allowed=ROBOT_TYPES)
        if isinstance(msg, Welcome):
            # the round trip alone: less the time the hello waited for a robot still starting
            self.handshake_s = max(0.0, time.monotonic() - hello_at - msg.held_s)
            async with self._lock:
                restart = self.sender.begin_session(msg)
                if restart is not None:
                    self._end_session(restart)
                self.halted = msg.halted
                self.command_watch.interval = msg.heartbeat_s
                await self._send_all(self.sender.on_welcome(msg))
                self.connected.set()
            return
        if isinstance(msg, Heartbeat):
            self.heartbeats_heard += 1
            return
        if isinstance(msg, Halted):
            self.halted = f"{msg.cause.value}: {msg.detail}"
            log.warning("the robot halted by itself: %s", self.halted)
            return
        if isinstance(msg, Rejected) and msg.final and msg.comm_id is None:
            # what decode_message makes of an unreadable message (the robot's own refusals of a
            # message are never final): the robot sent something this console cannot read
            raise TeleprogError(f"unreadable message from the robot: {msg.reason.value}: {msg.detail}")
        self._dispatch(msg)

    def _end_session(self, restart: SessionRestart) -> None:
        """Fail what waits on the old session (its fate is unknown) and tell the listeners."""
        self.restarts.append(restart)
        error = RobotRestarted(restart)
        for futures in (self._answers, self._acks, self._finals):
            for future in futures.values():
                if not future.done():
                    future.set_exception(error)
                    future.exception()  # nobody may be waiting: no "never retrieved" warning
            futures.clear()
        self.buffer_full = None
        for listener in self._restart_listeners:
            self._delivery.post(listener, restart)

    async def _heartbeats(self, ws: ClientConnection) -> None:
        """A heartbeat every interval once greeted, through the one writer."""
        seq = 0
        while True:
            await asyncio.sleep(HEARTBEAT_INTERVAL_S)
            if not self.connected.is_set():
                continue
            async with self._lock:
                if self._ws is not ws:
                    return
                await ws.send(encode_message(Heartbeat(seq=seq)))
            seq += 1

    async def _close_if_silent(self, ws: ClientConnection, watch: SilenceWatch, what: str) -> None:
        """Close a socket that stays open while nothing arrives on it (a frozen link or robot).
        Counts only once something arrived on this socket: the first arrival takes a delay (or
        two), which is no silence. Looks every twentieth of ``reconnect_silence_s``, or every
        interval of the watch when that is longer (a telemetry watch's 20 ms would wake the loop
        50 times a second to test a limit of seconds)."""
        opened = self.now()
        while True:
            await asyncio.sleep(max(watch.interval, self.reconnect_silence_s / 20.0))
            now = self.now()
            if watch.last_heard is None or watch.last_heard < opened:
                continue
            age = now - watch.last_heard
            if age > self.reconnect_silence_s:
                log.warning("%s to %s silent for %.1f s with its socket open: reconnecting", what, self.url, age)
                ws.transport.abort()
                return

    def _dispatch(self, msg: BaseModel) -> None:
        before = self.sender.last_report_seq
        cmd = self.sender.unacked(msg.command_id) if isinstance(msg, RecoveryAck) else None
        self.sender.on_message(msg)
        answered = isinstance(msg, Accepted) or (isinstance(msg, Rejected) and msg.final and msg.comm_id is not None)
        if answered:
            if isinstance(msg, Accepted):
                self.buffer_full = None
            elif msg.reason is RejectReason.BUFFER_FULL:
                self.buffer_full = f"communication {msg.comm_id}: {msg.detail}"
            future = self._answers.setdefault(msg.comm_id, asyncio.get_running_loop().create_future())
            if not future.done():
                future.set_result(msg)
        elif isinstance(msg, Rejected):
            self.refused = f"{msg.reason.value}: {msg.detail}"
            if msg.reason is RejectReason.BUFFER_FULL:
                self.buffer_full = msg.detail
        elif isinstance(msg, StatusReport) and msg.report_seq > before:
            self.reports.append(msg)
            self._delivery.post(self._deliver_report, msg)
        elif isinstance(msg, RecoveryAck):
            if cmd is not None and msg.applied and isinstance(cmd, (Resume, SkipCurrent, AbortFlush)):
                self.halted = None
            if cmd is not None and not msg.applied:
                self.refused = f"{cmd.type} #{cmd.command_id} not applied: {msg.detail}"
            future = self._acks.get(msg.command_id)
            if future is not None and not future.done():
                future.set_result(msg)

    # -- the telemetry channel ------------------------------------------------------------------
    async def _telemetry_loop(self) -> None:
        fast = {"create_connection": functools.partial(_TelemetryConnection, on_message=self._telemetry_message)} if _FAST_TELEMETRY else {}
        while not self._closing:
            watchdog: asyncio.Task | None = None
            try:
                async with connect(
                    f"{self.url}/telemetry", max_size=MAX_MESSAGE_BYTES, compression=None, open_timeout=5, close_timeout=1,
                    **fast,
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

    # -- the listeners' thread ------------------------------------------------------------------
    def _deliver_report(self, msg: StatusReport) -> None:
        """On the delivery thread: the listeners take a report, then a final one settles its
        ``wait_final`` (on the loop), so whoever waits sees what the listeners made of it."""
        for listener in self._report_listeners:
            try:
                listener(msg)
            except Exception as exc:  # noqa: BLE001 - a listener must not end the channel
                self._record_error(f"a report listener (statement {msg.number})", exc)
        if msg.state.final and self._loop is not None and not self._loop.is_closed():
            try:
                self._loop.call_soon_threadsafe(self._settle_final, msg)
            except RuntimeError:  # the loop closed meanwhile: nobody waits any more
                pass

    def _settle_final(self, msg: StatusReport) -> None:
        future = self._final_future(msg.number)
        if not future.done():
            future.set_result(msg)
