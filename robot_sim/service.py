"""The telerobot process: ``RobotCore`` behind two WebSocket channels, driven by a real clock.

* ``/command``: text messages (``shared.wire.messages``) and binary command units
  (``shared.wire.units``) in; answers, status reports and acknowledgements out, written by one
  task per connection so they leave in the order the core produced them.
* ``/telemetry``: one fixed-size binary frame (``shared.wire.telemetry``) to every subscriber at
  ``telemetry_rate``.
* ``GET /health``: a JSON line (``core_ready``, robot state, buffer length, statements numbered, ``halted``:
  why the robot holds by itself, or null).

Heartbeats and the silence halt are the core's (``robot_sim.core``): ``heartbeat_s`` and
``silence_limit_s`` are settings. No message and no servo tick can end the process: each handler
and each tick has a last-resort boundary that logs the error and keeps serving.

Both channels require the robot's credential (``shared.wire.credential``; ``robot_sim.credential``
says which): an upgrade without it is refused with HTTP 401 and one line, before any message.

One console connection at a time on ``/command``: a second one replaces the first (the console
reconnecting through a restarted link must not wait for the old socket to time out).
"""

from __future__ import annotations

import asyncio
import http
import json
import logging
import time
from collections.abc import Callable

from typing import TYPE_CHECKING

from pydantic import BaseModel
from websockets.asyncio.server import ServerConnection, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Response

from robot_sim.credential import RobotCredential, given_credential, made_credential
from robot_sim.settings import RobotSettings
from shared.startup_trace import mark
from shared.wire import credential as door
from shared.wire.messages import Rejected, RejectReason, Welcome, encode_message

if TYPE_CHECKING:
    from robot_sim.core import RobotCore

log = logging.getLogger("teleprog.robot")

MAX_MESSAGE_BYTES = 4 << 20


__all__ = ["RobotService", "RobotSettings"]


class RobotService:
    """Sockets and clock around one ``RobotCore``."""

    def __init__(self, settings: RobotSettings) -> None:
        self.settings = settings
        self.core: RobotCore | None = None
        """Built by ``run`` (``build_core``): before the sockets listen, or with ``listen_first``
        right after (the collision model takes a moment, and a console's hello needs one link
        delay to arrive anyway)."""
        self._core_ready: asyncio.Event | None = None
        self._command: ServerConnection | None = None
        self._outbox: asyncio.Queue[BaseModel] | None = None
        self._telemetry: set[ServerConnection] = set()
        self._server = None
        self.port = settings.port
        self.credential: RobotCredential | None = given_credential(settings)
        """Required of every connection; made (and written to a user-only file) once the port is
        known when the settings give none."""
        self.refused = 0
        """Connections refused for a missing or wrong credential."""
        self._refusal_logged_at = -1e9

    def build_core(self) -> RobotCore:
        """The cell, the simulated world and the executor (with its collision model)."""
        # imported here, not at the top: the sockets listen before the collision and motion code loads
        from robot_sim.core import RobotCore
        from robot_sim.executor import Executor
        from robot_sim.worlds import make_world
        from shared.cells.loader import load_cell
        from shared.collision import model_cache

        settings = self.settings
        model_cache.configure(settings.cache_dir)  # the collision model, built once per robot and cell
        cell = load_cell(settings.cell)
        world = make_world(cell, settings.world, servo_period=1.0 / settings.executor.servo_rate)
        return RobotCore(
            Executor(cell, world, settings.executor),
            heartbeat_s=settings.heartbeat_s,
            silence_limit_s=settings.silence_limit_s,
        )

    # -- lifecycle ------------------------------------------------------------------------------
    async def run(self, on_ready: Callable[[int], None] | None = None) -> None:
        self._core_ready = asyncio.Event()
        if not self.settings.listen_first:
            self.core = self.build_core()
            self._core_ready.set()
            mark("robot", "core ready")
        async with serve(
            self._handle,
            self.settings.host,
            self.settings.port,
            process_request=self._process_request,
            max_size=MAX_MESSAGE_BYTES,
            compression=None,
        ) as server:
            self._server = server
            self.port = next(iter(server.sockets)).getsockname()[1]
            if self.credential is None:  # no await since serve: nothing was let in without one
                self.credential = made_credential(self.port)
                log.info("no credential given: made one, written to %s (give the console --robot-credential-file %s)",
                         self.credential.file, self.credential.file)
            mark("robot", "listening")
            if on_ready:
                on_ready(self.port)
            if self.core is None:
                # listening first: a console (through the link) connects at once and its hello
                # waits in the socket until the core is there; /health says core_ready meanwhile
                self.core = await asyncio.to_thread(self.build_core)
                self._core_ready.set()
                mark("robot", "core ready")
            await asyncio.gather(self._servo(), self._publish())

    def _process_request(self, connection: ServerConnection, request) -> Response | None:
        if request.path == "/health":
            body = json.dumps(self.health()).encode()
            return Response(http.HTTPStatus.OK, "OK", Headers({"Content-Type": "application/json"}), body)
        if request.path not in ("/command", "/telemetry"):
            return connection.respond(http.HTTPStatus.NOT_FOUND, f"no channel at {request.path}\n")
        if self.credential is None:
            return connection.respond(http.HTTPStatus.SERVICE_UNAVAILABLE, "the robot is starting\n")
        reason = door.refusal(request.headers.get(door.HEADER), self.credential.secret)
        if reason is not None:
            self.refused += 1
            now = time.monotonic()
            if now - self._refusal_logged_at > 60.0:  # a console retrying with no credential: a line a minute
                self._refusal_logged_at = now
                log.warning("refused a connection to %s from %s (%d so far): %s", request.path,
                            connection.remote_address, self.refused, reason)
            return connection.respond(http.HTTPStatus.UNAUTHORIZED, reason + "\n")
        return None

    def health(self) -> dict[str, object]:
        """What ``GET /health`` answers; ``core_ready`` is false (state ``starting``) while the
        core is being built after the sockets began listening."""
        core = self.core
        if core is None:
            return {"status": "ok", "core_ready": False, "state": "starting", "queued": 0, "current": None,
                    "numbered": 0, "console": False, "halted": None, "refused": self.refused}
        ex = core.executor
        return {
            "status": "ok",
            "core_ready": True,
            "state": ex.state.name.lower(),
            "queued": len(ex.queue),
            "current": ex.current_number,
            "numbered": core.receiver.next_number - 1,
            "console": core.connected,
            "halted": ex.halted,
            "refused": self.refused,
        }

    # -- channels ---------------------------------------------------------------------------------
    async def _handle(self, ws: ServerConnection) -> None:
        if ws.request.path == "/telemetry":
            self._telemetry.add(ws)
            try:
                await ws.wait_closed()
            finally:
                self._telemetry.discard(ws)
            return
        await self._command_connection(ws)

    async def _command_connection(self, ws: ServerConnection) -> None:
        try:
            early, held_s = await self._hold_until_core(ws)
        except ConnectionClosed:
            return
        core = self.core
        assert core is not None  # set before _core_ready
        if self._command is not None:
            log.info("a new console connection replaces the previous one")
            await self._command.close(1001, "replaced by a new console connection")
        self._command = ws
        outbox: asyncio.Queue[BaseModel] = asyncio.Queue()
        self._outbox = outbox
        core.connect()
        writer = asyncio.create_task(self._write(ws, outbox))

        def take(message: str | bytes) -> None:
            nonlocal held_s
            try:
                replies = core.on_unit(message) if isinstance(message, bytes) else core.on_text(message)
            except Exception as exc:  # noqa: BLE001 - the core has its own boundary; this is the last one
                log.exception("internal error while handling a message")
                replies = [Rejected(reason=RejectReason.BAD_MESSAGE, final=False,
                                    detail=f"internal error: {type(exc).__name__}")]
            for r in replies:
                if held_s and isinstance(r, Welcome):  # the console subtracts it from its round trip
                    r, held_s = r.model_copy(update={"held_s": held_s}), 0.0
                outbox.put_nowait(r)

        try:
            for message in early:
                take(message)
            async for message in ws:
                take(message)
        except ConnectionClosed:
            pass
        finally:
            if self._command is ws:
                self._command = None
                self._outbox = None
                core.disconnect()
            writer.cancel()

    async def _hold_until_core(self, ws: ServerConnection) -> tuple[list[str | bytes], float]:
        """Until the core is built (``listen_first``): what arrives, in order, and how long the
        first message waited for the core (0 when it was ready)."""
        ready = self._core_ready
        if ready is None or ready.is_set():
            return [], 0.0
        early: list[str | bytes] = []
        first_at: float | None = None
        waiting = asyncio.ensure_future(ready.wait())
        try:
            while not waiting.done():
                recv = asyncio.ensure_future(ws.recv())
                await asyncio.wait({recv, waiting}, return_when=asyncio.FIRST_COMPLETED)
                if recv.done():
                    early.append(recv.result())  # raises ConnectionClosed when the console left
                    first_at = first_at if first_at is not None else time.monotonic()
                else:
                    recv.cancel()  # websockets: a cancelled recv() loses nothing
                    await asyncio.gather(recv, return_exceptions=True)
        finally:
            waiting.cancel()
        return early, (0.0 if first_at is None else time.monotonic() - first_at)

    async def _write(self, ws: ServerConnection, outbox: asyncio.Queue[BaseModel]) -> None:
        try:
            while True:
                message = await outbox.get()
                try:
                    text = encode_message(message)
                except Exception:  # noqa: BLE001 - one message that cannot be encoded is dropped, logged
                    log.exception("cannot encode %s", type(message).__name__)
                    continue
                await ws.send(text)
        except (ConnectionClosed, asyncio.CancelledError):
            return

    # -- clocks ------------------------------------------------------------------------------------
    async def _servo(self) -> None:
        """Tick the executor at its servo rate, catching up if the event loop was late."""
        core = self.core
        assert core is not None  # the clocks start once the core is built
        dt = core.executor.dt
        next_t = time.monotonic()
        while True:
            next_t += dt
            try:
                out = core.tick()
            except Exception:  # noqa: BLE001 - the core has its own boundary; this is the last one
                log.exception("internal error in the servo tick")
                out = []
            for report in out:
                if self._outbox is not None:
                    self._outbox.put_nowait(report)
            now = time.monotonic()
            if next_t - now > 0:
                await asyncio.sleep(next_t - now)
            elif now - next_t > 1.0:  # far behind (suspended?): do not replay a second of servo ticks
                next_t = now
            else:
                await asyncio.sleep(0)

    async def _publish(self) -> None:
        core = self.core
        assert core is not None  # the clocks start once the core is built
        period = 1.0 / self.settings.telemetry_rate
        next_t = time.monotonic()
        while True:
            next_t += period
            try:
                frame = core.telemetry()
            except Exception:  # noqa: BLE001 - a frame that cannot be made is skipped, logged
                log.exception("cannot make a telemetry frame")
                await asyncio.sleep(period)
                continue
            for ws in list(self._telemetry):
                try:
                    await ws.send(frame)
                except ConnectionClosed:
                    self._telemetry.discard(ws)
            await asyncio.sleep(max(0.0, next_t - time.monotonic()))
