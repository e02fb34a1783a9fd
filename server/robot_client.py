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
"""

from __future__ import annotations

import asyncio
import logging
import time
import uuid
from collections.abc import Callable, Iterable

from pydantic import BaseModel
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidURI

from shared.errors import TeleprogError
from shared.language.statements import Statement
from shared.wire.messages import (
    AbortFlush,
    Accepted,
    Recovery,
    RecoveryAck,
    Rejected,
    Resume,
    SkipCurrent,
    StatusReport,
    Stop,
    Welcome,
    decode_message,
    encode_message,
)
from shared.wire.session import CommandSender
from shared.wire.telemetry import TelemetryError, TelemetryFrame, decode_frame

log = logging.getLogger("teleprog.client")

MAX_MESSAGE_BYTES = 4 << 20


class CommunicationRejected(TeleprogError):
    """The robot refused a whole communication; ``answer`` says why and where."""

    def __init__(self, answer: Rejected) -> None:
        self.answer = answer
        where = f" at statement {answer.statement_index + 1}" if answer.statement_index is not None else ""
        super().__init__(f"robot rejected communication {answer.comm_id}{where}: {answer.reason.value}: {answer.detail}")


class RobotClient:
    """Command and telemetry channels of one robot, with reconnects and exactly-once submission."""

    def __init__(self, url: str, client_id: str | None = None, reconnect_delay: float = 0.2) -> None:
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
        self._ws: ClientConnection | None = None
        self._lock = asyncio.Lock()  # one writer: welcome replays and new units never interleave
        self._answers: dict[int, asyncio.Future[Accepted | Rejected]] = {}
        self._acks: dict[int, asyncio.Future[RecoveryAck]] = {}
        self._finals: dict[int, asyncio.Future[StatusReport]] = {}
        self._report_listeners: list[Callable[[StatusReport], None]] = []
        self._telemetry_listeners: list[Callable[[TelemetryFrame], None]] = []
        self._tasks: list[asyncio.Task] = []
        self._closing = False

    # -- lifecycle ------------------------------------------------------------------------------
    async def __aenter__(self) -> RobotClient:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def start(self, timeout: float = 10.0) -> None:
        """Open both channels; returns once the command channel has its welcome."""
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

    def on_report(self, listener: Callable[[StatusReport], None]) -> None:
        self._report_listeners.append(listener)

    def on_telemetry(self, listener: Callable[[TelemetryFrame], None]) -> None:
        self._telemetry_listeners.append(listener)

    # -- commands -------------------------------------------------------------------------------
    async def submit(self, statements: Iterable[Statement], timeout: float | None = None) -> tuple[int, ...]:
        """Send a communication; return the numbers the robot gave its statements.

        Raises ``CommunicationRejected`` when the robot refuses it. The communication is kept
        and resent across reconnects until answered, so waiting survives a cut link.
        """
        async with self._lock:
            comm_id, units = self.sender.submit(list(statements))
            future = self._answers.setdefault(comm_id, asyncio.get_running_loop().create_future())
            if self._ws is not None and self.connected.is_set():
                await self._send_all(units)
        answer = await asyncio.wait_for(asyncio.shield(future), timeout)
        if isinstance(answer, Rejected):
            raise CommunicationRejected(answer)
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
            cmd = self.sender.command(kind, **fields)
            future = self._acks.setdefault(cmd.command_id, asyncio.get_running_loop().create_future())
            if self._ws is not None and self.connected.is_set():
                await self._send_all([cmd])
        return await asyncio.wait_for(asyncio.shield(future), timeout)

    async def wait_final(self, numbers: Iterable[int], timeout: float | None = None) -> dict[int, StatusReport]:
        """Wait until every numbered statement has its final status report."""
        futures = {n: self._final_future(n) for n in numbers}
        await asyncio.wait_for(asyncio.gather(*futures.values()), timeout)
        return {n: f.result() for n, f in futures.items()}

    def _final_future(self, number: int) -> asyncio.Future[StatusReport]:
        if number not in self._finals:
            self._finals[number] = asyncio.get_running_loop().create_future()
        return self._finals[number]

    # -- the command channel --------------------------------------------------------------------
    async def _send_all(self, items: list[bytes | BaseModel]) -> None:
        assert self._ws is not None
        for item in items:
            await self._ws.send(item if isinstance(item, bytes) else encode_message(item))

    async def _command_loop(self) -> None:
        while not self._closing:
            try:
                async with connect(f"{self.url}/command", max_size=MAX_MESSAGE_BYTES, compression=None, open_timeout=5) as ws:
                    self._ws = ws
                    hello_at = time.monotonic()
                    await ws.send(encode_message(self.sender.hello()))
                    async for raw in ws:
                        msg = decode_message(raw)
                        if isinstance(msg, Welcome):
                            self.handshake_s = time.monotonic() - hello_at
                            async with self._lock:
                                await self._send_all(self.sender.on_welcome(msg))
                                self.connected.set()
                            continue
                        self._dispatch(msg)
            except (OSError, ConnectionClosed, InvalidHandshake, asyncio.TimeoutError) as exc:
                if not self._closing:
                    log.info("command channel to %s down: %s", self.url, exc or type(exc).__name__)
            except InvalidURI as exc:
                log.error("bad robot URL %s: %s", self.url, exc)
                return
            finally:
                self._ws = None
                if self.connected.is_set():
                    self.reconnects += 1
                self.connected.clear()
            await asyncio.sleep(self.reconnect_delay)

    def _dispatch(self, msg: BaseModel) -> None:
        before = self.sender.last_report_seq
        self.sender.on_message(msg)
        answered = isinstance(msg, Accepted) or (isinstance(msg, Rejected) and msg.final and msg.comm_id is not None)
        if answered:
            future = self._answers.setdefault(msg.comm_id, asyncio.get_running_loop().create_future())
            if not future.done():
                future.set_result(msg)
        elif isinstance(msg, StatusReport) and msg.report_seq > before:
            self.reports.append(msg)
            if msg.state.final:
                future = self._final_future(msg.number)
                if not future.done():
                    future.set_result(msg)
            for listener in self._report_listeners:
                listener(msg)
        elif isinstance(msg, RecoveryAck):
            future = self._acks.get(msg.command_id)
            if future is not None and not future.done():
                future.set_result(msg)

    # -- the telemetry channel ------------------------------------------------------------------
    async def _telemetry_loop(self) -> None:
        while not self._closing:
            try:
                async with connect(f"{self.url}/telemetry", max_size=MAX_MESSAGE_BYTES, compression=None, open_timeout=5) as ws:
                    async for raw in ws:
                        if not isinstance(raw, bytes):
                            continue
                        try:
                            frame = decode_frame(raw)
                        except TelemetryError as exc:
                            log.warning("bad telemetry frame: %s", exc)
                            continue
                        self.telemetry = frame
                        for listener in self._telemetry_listeners:
                            listener(frame)
            except (OSError, ConnectionClosed, InvalidHandshake, asyncio.TimeoutError):
                pass
            except InvalidURI:
                return
            await asyncio.sleep(self.reconnect_delay)
