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
* the robot's door: both channels present ``credential`` (``shared.wire.credential``); a robot
  (or a link relaying its answer) that refuses the connection for it is kept in ``door`` with the
  robot's reason, logged once, shown in the link view, and retried quietly;
* a welcome from another robot session (the robot restarted) fails every waiting submission,
  command and final with ``RobotRestarted``: their fate is unknown, and nothing of the old session
  is sent to the new robot.
"""

from __future__ import annotations

import asyncio
import logging
import os
import threading
import time
import uuid
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from pydantic import BaseModel
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidStatus, InvalidURI

from server.delivery import Delivery
from server.robot_telemetry import TelemetryChannel
from shared.errors import TeleprogError
from shared.startup_trace import mark
from shared.language.statements import Statement
from shared.wire import credential as door_keys
from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S, HEARTBEAT_INTERVAL_S, SilenceWatch
from shared.wire.messages import (
    MAX_ROBOT_MESSAGE_BYTES,
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
from shared.wire.telemetry import FRAME_RATE_HZ, TelemetryFrame

log = logging.getLogger("teleprog.client")

MAX_MESSAGE_BYTES = 4 << 20
REFUSED_CLOSE_CODE = 1008
"""Close code with which a link relays the robot's refusal (``server.relay.link_relay``)."""
RECONNECT_SILENCE_FACTOR = 10.0
"""An open socket silent for this many silence limits is closed and opened again."""


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
    door: str | None = None
    """Why the robot refuses this console's connections (no or another credential), until one is let in."""
    """Telemetry frames received and decoded since the client started (every connection)."""


@dataclass(frozen=True)
class RobotAccount:
    """The robot's first welcome to this client and the status reports that came after it by the
    time a listener asked (``RobotClient.on_account``)."""

    welcome: Welcome
    reports: tuple[StatusReport, ...]
    client_id: str = ""
    """this client's identity: what the robot ran for it is its own history (others' is not listed)"""


class RobotClient(TelemetryChannel):
    """Command and telemetry channels of one robot, with reconnects and exactly-once submission."""

    def __init__(
        self,
        url: str,
        client_id: str | None = None,
        reconnect_delay: float = 0.2,
        silence_limit_s: float = DEFAULT_SILENCE_LIMIT_S,
        reconnect_silence_s: float | None = None,
        credential: str | None = None,
        kept_identity: bool = False,
    ) -> None:
        self.url = url.rstrip("/")
        # presented on both channels, never logged; None: TELEPROG_ROBOT_CREDENTIAL's, if set
        self._headers = door_keys.headers(credential if credential is not None else os.environ.get(door_keys.ENV_VAR))
        self.door: str | None = None
        # kept_identity: client_id came from an earlier process (nothing leaves before the first welcome here)
        self.sender = CommandSender(client_id or f"console-{uuid.uuid4().hex[:12]}", kept_identity=kept_identity and bool(client_id))
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
        self._account_listeners: list[Callable[[RobotAccount], None]] = []
        self._account: Welcome | None = None  # the first welcome
        self._account_lock = threading.Lock()  # listeners register on another thread than the loop's
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

    def on_account(self, listener: Callable[[RobotAccount], None]) -> None:
        """``listener(account)`` once, on the listeners' thread: the robot's first welcome to this
        client (what it holds and has run when this console arrived: a console that started again
        shows it) and the reports that came since. At that welcome if it has not come yet (the
        reports then follow through ``on_report``); at once if it has (the console's session
        attaches after the early connection of ``teleprog up``)."""
        with self._account_lock:
            self._account_listeners.append(listener)
            if self._account is not None:
                self._delivery.post(listener, RobotAccount(self._account, tuple(self.reports), self.sender.client_id))

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
            telemetry_frames=self.telemetry_frames, door=self.door,
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
                    f"{self.url}/command", max_size=MAX_MESSAGE_BYTES, compression=None, open_timeout=5, close_timeout=1,
                    additional_headers=self._headers,
                ) as ws:
                    self._ws = ws
                    self._door_open()
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
            except InvalidStatus as exc:  # the robot refused the upgrade (its door)
                self._door_closed(exc.response.status_code, exc.response.body)
            except ConnectionClosed as exc:
                if exc.rcvd is not None and exc.rcvd.code == REFUSED_CLOSE_CODE:  # a link relaying the robot's refusal
                    self._door_closed(None, exc.rcvd.reason.encode())
                elif not self._closing and not said_down:
                    log.info("command channel to %s down: %s (retrying quietly)", self.url, exc)
                    said_down = True
            except (OSError, InvalidHandshake, asyncio.TimeoutError) as exc:
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

    def _door_closed(self, status: int | None, body: bytes | None) -> None:
        """The robot refused this console's connection: why, kept for the link view (logged once per reason)."""
        text = (body or b"").decode("utf-8", "replace").strip().splitlines()
        reason = (text[0] if text else f"HTTP {status}")[:300]
        if reason != self.door:
            log.error("the robot at %s refuses this console: %s", self.url, reason)
        self.door = reason

    def _door_open(self) -> None:
        if self.door is not None:
            log.info("the robot at %s lets this console in", self.url)
        self.door = None

    async def _take(self, raw: str | bytes, hello_at: float) -> None:
        """One message from the robot."""
        msg = decode_message(raw, allowed=ROBOT_TYPES, max_bytes=MAX_ROBOT_MESSAGE_BYTES)
        if isinstance(msg, Welcome):
            # the round trip alone: less the time the hello waited for a robot still starting
            self.handshake_s = max(0.0, time.monotonic() - hello_at - msg.held_s)
            async with self._lock:
                first = self.sender.session_id is None
                restart = self.sender.begin_session(msg)
                if restart is not None:
                    self._end_session(restart)
                if (renumbered := self.sender.renumbered) is not None:  # the robot knew this identity
                    self.sender.renumbered = None
                    self._answers = {renumbered.comms.get(c, c): f for c, f in self._answers.items()}
                    self._acks = {renumbered.commands.get(c, c): f for c, f in self._acks.items()}
                if first:  # what the robot holds and ran, before anything it replays
                    with self._account_lock:
                        self._account = msg
                        for listener in self._account_listeners:
                            self._delivery.post(listener, RobotAccount(msg, (), self.sender.client_id))
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
        if isinstance(msg, (Accepted, Rejected)) and msg.comm_id is not None and msg.comm_id < self.sender.first_comm:
            return  # an answer to an earlier process under this identity, replayed
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
