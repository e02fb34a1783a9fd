"""Real-process helpers for the link tests: the link as a subprocess, a stand-in robot, a client.

The telerobot does not exist yet, so ``StandInRobot`` serves the robot's two paths with the real
wire code: ``/command`` runs a ``shared.wire.session.CommandReceiver`` and a toy executor that
finishes each statement after a few milliseconds; ``/telemetry`` sends real telemetry frames at
50 Hz. Both record what arrives and when. ``CommandClient`` is a console end with reconnects,
built on ``CommandSender``.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

from websockets.asyncio.client import connect
from websockets.asyncio.server import serve
from websockets.exceptions import ConnectionClosed, InvalidStatus

from shared.wire.messages import RobotSnapshot, RobotState, StatementState, Welcome, decode_message, encode_message
from shared.wire.session import CommandReceiver, CommandSender
from support import ServerProcess, free_port, robot_headers

SNAP = RobotSnapshot(state=RobotState.IDLE, q=(0.0,) * 6, base_p_tool=(0.4, 0.0, 0.3), tool_rpy=(0.0, 0.0, 0.0))


class LinkProcess(ServerProcess):
    """``teleprog link`` relaying to the robot at ``robot_port``, as a real process."""

    def __init__(self, robot_port: int, tmp_path: Path, *flags: str, port: int | None = None) -> None:
        super().__init__(tmp_path, "link", "--robot", f"ws://127.0.0.1:{robot_port}", *flags, port=port, timeout=30.0)
        self.robot_port = robot_port


@dataclass
class Arrival:
    path: str
    payload: bytes | str
    at: float  # time.perf_counter() on arrival


@dataclass
class StandInRobot:
    """A robot stand-in on loopback: the real receiver on /command, real frames on /telemetry."""

    port: int = field(default_factory=free_port)
    step_s: float = 0.002
    telemetry_hz: float = 0.0  # 0: send no telemetry on its own
    arrivals: list[Arrival] = field(default_factory=list)
    buffered: list[tuple[int, object]] = field(default_factory=list)
    connections: int = 0

    def __post_init__(self) -> None:
        self.receiver = CommandReceiver("standin-1")
        self._out: asyncio.Queue | None = None  # the writer queue of the bound /command connection
        self._server = None
        self._exec: asyncio.Queue = asyncio.Queue()
        self._exec_task: asyncio.Task | None = None

    async def start(self) -> None:
        self._server = await serve(self._handle, "127.0.0.1", self.port, compression=None, max_size=None,
                                   max_queue=None, ping_interval=None)
        if self._exec_task is None:
            self._exec_task = asyncio.create_task(self._executor())

    async def stop(self) -> None:
        """The robot process goes away: the server and every connection close."""
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
            self._server = None

    async def close(self) -> None:
        await self.stop()
        if self._exec_task is not None:
            self._exec_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._exec_task

    def _emit(self, messages) -> None:
        if self._out is not None:
            for m in messages:
                self._out.put_nowait(encode_message(m))

    async def _executor(self) -> None:
        while True:
            number = await self._exec.get()
            self._emit([self.receiver.report(number, StatementState.RUNNING)])
            await asyncio.sleep(self.step_s)
            self._emit([self.receiver.report(number, StatementState.DONE, robot=SNAP)])

    async def _handle(self, ws) -> None:
        self.connections += 1
        path = ws.request.path
        if path == "/command":
            await self._command(ws)
        else:
            await self._telemetry(ws)

    async def _command(self, ws) -> None:
        out: asyncio.Queue = asyncio.Queue()

        async def writer() -> None:
            while True:
                await ws.send(await out.get())

        task = asyncio.create_task(writer())
        try:
            async for raw in ws:
                self.arrivals.append(Arrival("/command", raw, time.perf_counter()))
                step = self.receiver.on_unit(raw) if isinstance(raw, bytes) else self.receiver.on_text(raw)
                if isinstance(raw, str) and json.loads(raw).get("type") == "hello":
                    self._out = out  # bind before queueing the replay, so order holds
                self._emit(step.replies)
                for number, statement in step.accepted:
                    self.buffered.append((number, statement))
                    self._exec.put_nowait(number)
        except ConnectionClosed:
            pass
        finally:
            if self._out is out:
                self._out = None
                self.receiver.disconnect()
            task.cancel()

    async def _telemetry(self, ws) -> None:
        from shared.wire.messages import ControlMode
        from shared.wire.telemetry import TelemetryFrame, encode_frame

        async def sender() -> None:
            k = 0
            t0 = time.perf_counter()
            while self.telemetry_hz > 0:
                now = time.perf_counter()
                frame = TelemetryFrame(time=now, frame=k, state=RobotState.IDLE, mode=ControlMode.POSITION,
                                       statement=0, q=(0.0,) * 6, position=(0.4, 0.0, 0.3), rpy=(0.0, 0.0, 0.0))
                await ws.send(encode_frame(frame))
                k += 1
                await asyncio.sleep(max(0.0, t0 + k / self.telemetry_hz - time.perf_counter()))

        task = asyncio.create_task(sender())
        try:
            async for raw in ws:
                self.arrivals.append(Arrival("/telemetry", raw, time.perf_counter()))
        except ConnectionClosed:
            pass
        finally:
            task.cancel()


class CommandClient:
    """A console end that reconnects until every communication is answered and finished."""

    def __init__(self, url: str, client_id: str = "console-test", per_unit: int = 25) -> None:
        self.url = url
        self.sender = CommandSender(client_id, per_unit=per_unit)
        self.ws = None
        self.welcomed = False
        self.connects = 0
        self.closes: list[tuple[int | None, str | None]] = []

    async def submit(self, statements) -> None:
        _, units = self.sender.submit(statements)
        if self.ws is not None and self.welcomed:
            with contextlib.suppress(ConnectionClosed):
                for u in units:
                    await self.ws.send(u)

    def finished(self, total: int) -> bool:
        return self.sender.idle and all(self.sender.final_state(n) is not None for n in range(1, total + 1))

    async def run(self, total: int, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not self.finished(total):
            if time.monotonic() > deadline:
                raise TimeoutError(f"client not finished; outbox {list(self.sender.outbox)}")
            try:
                async with connect(self.url + "/command", compression=None, max_size=None, open_timeout=2, additional_headers=robot_headers()) as ws:
                    self.connects += 1
                    self.ws, self.welcomed = ws, False
                    await ws.send(encode_message(self.sender.hello()))
                    async for raw in ws:
                        msg = decode_message(raw)
                        if isinstance(msg, Welcome):
                            for item in self.sender.on_welcome(msg):
                                await ws.send(item if isinstance(item, bytes) else encode_message(item))
                            self.welcomed = True
                        else:
                            self.sender.on_message(msg)
                        if self.finished(total):
                            return
            except ConnectionClosed:
                pass
            except (OSError, InvalidStatus, TimeoutError):
                pass
            finally:
                if self.ws is not None:
                    self.closes.append((self.ws.close_code, self.ws.close_reason))
                self.ws, self.welcomed = None, False
            await asyncio.sleep(0.05)
