"""The delayed link as a process: an asyncio WebSocket relay around ``shared.link.core.LinkCore``.

The console (or any headless client) connects to the relay instead of the robot, on the same
paths the robot serves (``/command``, ``/telemetry``). For each incoming connection the relay opens
one connection to the robot on the same path and carries messages both ways through a
``LinkCore``, which decides when each one is due. One timer task per connection sleeps until the
next due time and sends what is due, in order.

Closing and faults, so that each end notices what a real line would show it:

* the console closes: what is in flight towards the robot still arrives, then (no earlier than one
  delay after the close) the relay closes the robot side;
* the robot side is lost (robot stopped or crashed): the relay logs it, counts it in ``/health``,
  delivers what was already in flight towards the console, then closes the console side with code
  1011 and the reason ``robot connection lost``. The relay itself keeps running; the console's
  next connection gets a fresh robot connection, so both ends run their ``hello``/``welcome``
  handshake again (``shared.wire.messages``) and nothing is silently re-routed;
* a fault of the core (a lost message): the line is down, so every open connection on it (both
  channels) is closed with 1011 ``link fault`` and new connections are refused (HTTP 503) until
  the outage ends;
* the robot refuses the connection (HTTP 401: no or another credential, which the relay passes
  through from the console's upgrade request unchanged and never logs): the console side is
  closed with 1008 and the robot's reason, counted as ``robot_refused``;
* an error inside the relay closes that connection's two sides with 1011 ``link error`` rather than
  leaving it open and silent.

``GET /health`` answers a JSON summary: connections, deliveries, faults, robot losses, and
``lateness_ms``, how long after their due time recent messages were handed to their socket.

Timing: each timer wakes ``EARLY_S`` before a due time and sleeps the rest with ``time.sleep``
(the event loop's own timers are millisecond-coarse), and the process asks Linux for a short
scheduler slice (``request_short_slice``) so its wake-ups are not held behind CPU-bound
neighbours.
"""

from __future__ import annotations

import asyncio
import ctypes
import itertools
import json
import logging
import os
import platform
import signal
import sys
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pydantic import Field, ValidationError
from pydantic_settings import BaseSettings, SettingsConfigDict

from websockets.asyncio.client import connect
from websockets.asyncio.server import serve
from websockets.exceptions import InvalidStatus

from shared.errors import InputError
from shared.startup_trace import mark
from shared.link.core import Delivery, Direction, LinkCore, LinkFault, LinkParams
from shared.wire import credential

log = logging.getLogger("teleprog.link")

CHANNEL_PATHS = ("/command", "/telemetry")
EARLY_S = 0.002
"""How far ahead of a due time the timer wakes, to finish the wait with a precise sleep."""
MAX_MESSAGE_BYTES = 4 << 20
"""Largest message relayed (4 MiB): above the protocol's own limits, so the relay never decides."""


class LinkSettings(BaseSettings, LinkParams):
    """The link process's typed settings: defaults, then ``TELEPROG_LINK_*`` variables, then flags."""

    model_config = SettingsConfigDict(env_prefix="TELEPROG_LINK_", extra="ignore", frozen=True)

    host: str = Field("127.0.0.1", description="address the link binds")
    port: int = Field(8765, ge=0, le=65535, description="port the console connects to (0: any free port)")
    robot: str = Field("ws://127.0.0.1:8766", description="the robot's WebSocket base URL")

    def params(self) -> LinkParams:
        return LinkParams(**{name: getattr(self, name) for name in LinkParams.model_fields})

    @classmethod
    def load(cls, **overrides: object) -> "LinkSettings":
        """Defaults, then the environment, then the given non-None values (command-line flags)."""
        try:
            return cls().with_overrides(**overrides)
        except ValidationError as exc:
            err = exc.errors()[0]
            name = ".".join(str(p) for p in err["loc"])
            raise InputError(f"link setting {name} (flag or TELEPROG_LINK_{name.upper()}): {err['msg']}") from None

    def with_overrides(self, **overrides: object) -> "LinkSettings":
        """A copy with the given non-None values replaced (command-line flags), validated."""
        values = {**self.model_dump(), **{k: v for k, v in overrides.items() if v is not None}}
        settings = LinkSettings.model_validate(values)
        if not settings.robot.startswith(("ws://", "wss://")):
            raise InputError(f"--robot {settings.robot!r}: expected a ws:// or wss:// URL")
        return settings


@dataclass
class LinkStats:
    connections: int = 0
    open: int = 0
    delivered: dict[str, int] = field(default_factory=lambda: {d.value: 0 for d in Direction})
    faults: int = 0
    robot_losses: int = 0
    robot_unreachable: int = 0
    robot_refused: int = 0
    lateness_s: deque = field(default_factory=lambda: deque(maxlen=10_000))
    """How long after its due time each recent delivery was handed to the socket."""

    def as_json(self) -> dict:
        late = np.array(self.lateness_s) * 1e3 if self.lateness_s else np.zeros(1)
        return {
            "connections": self.connections, "open": self.open, "delivered": dict(self.delivered),
            "faults": self.faults, "robot_losses": self.robot_losses, "robot_unreachable": self.robot_unreachable,
            "robot_refused": self.robot_refused,
            "lateness_ms": {"p50": round(float(np.percentile(late, 50)), 3), "p99": round(float(np.percentile(late, 99)), 3),
                            "max": round(float(late.max()), 3), "n": len(self.lateness_s)},
        }


class _Pipe:
    """One console connection and its robot connection, joined through a LinkCore."""

    def __init__(self, relay: "LinkRelay", console, robot, core: LinkCore, path: str) -> None:
        self.relay = relay
        self.ends = {Direction.UP: robot, Direction.DOWN: console}  # where each direction delivers
        self.core = core
        self.path = path
        self.loop = asyncio.get_running_loop()
        self.wake = asyncio.Event()
        self.wake_at = float("-inf")  # when the timer wakes next; -inf while it is busy (it rereads the core)
        self.closing: dict[Direction, float] = {}  # direction -> time after which its target closes
        self.close_reason: dict[Direction, tuple[int, str]] = {}
        self.tearing_down = False  # set by the relay's own closing, so readers do not report it
        self.done = asyncio.Event()

    async def read(self, source, direction: Direction) -> None:
        """Feed every message of ``source`` into the core; note when the source ends."""
        try:
            async for message in source:
                due = self.core.send(self.loop.time(), direction, message)
                if due is not None and due < self.wake_at:  # else the timer is already set early enough
                    self.wake.set()
        except Exception as exc:  # ConnectionClosedError and friends: the source is gone
            log.debug("%s %s reader ended: %r", self.path, direction.value, exc)
        finally:
            if self.tearing_down:  # closed from here, not ended by the other side
                return
            now = self.loop.time()
            if direction is Direction.UP:
                self._close_after(Direction.UP, now, 1000, "console closed")
            else:
                self.relay.stats.robot_losses += 1
                log.warning("link %s: robot connection lost (code %s); closing the console side",
                            self.path, getattr(source, "close_code", None))
                self._close_after(Direction.DOWN, now, 1011, "robot connection lost")

    def _close_after(self, direction: Direction, now: float, code: int, reason: str) -> None:
        if direction not in self.closing:
            self.closing[direction] = now + self.core.params.delay_s
            self.close_reason[direction] = (code, reason)
        self.wake.set()

    async def run_timer(self) -> None:
        """The timer task; a failure in it closes the pipe instead of leaving it hanging."""
        try:
            await self._timer()
        except asyncio.CancelledError:
            raise
        except Exception:
            log.exception("link %s: timer failed; closing both sides", self.path)
            await self._close_all(1011, "link error")

    async def _timer(self) -> None:
        """Sleep to the next due time, hand out what is due, close ends whose closing is due.

        The event loop's own timers wake up to a millisecond late (epoll counts whole
        milliseconds), so the timer wakes ``EARLY_S`` ahead and sleeps the rest precisely.
        """
        while True:
            due = self.core.next_due()
            wait = None if due is None else due - self.loop.time()
            if wait is not None and 0.0 < wait <= EARLY_S:
                time.sleep(wait)  # short and precise; blocks the loop < 2 ms
            now = self.loop.time()
            for event in self.core.poll(now):
                if isinstance(event, LinkFault):
                    await self._fault(event)
                    return
                await self._deliver(event)
            now = self.loop.time()
            for direction, at in list(self.closing.items()):
                if now >= at and self.core.in_flight(direction) == 0:
                    await self._close_all(*self.close_reason[direction])
                    return
            wake_at = [t for t in (self.core.next_due(), *self.closing.values()) if t is not None]
            self.wake.clear()
            self.wake_at = min(wake_at) if wake_at else float("inf")
            handle = self.loop.call_at(self.wake_at - EARLY_S, self.wake.set) if wake_at else None
            await self.wake.wait()
            self.wake_at = float("-inf")  # awake: every arrival is noticed by the next turn anyway
            if handle is not None:
                handle.cancel()

    async def _deliver(self, d: Delivery) -> None:
        target = self.ends[d.direction]
        try:
            await target.send(d.payload)
            self.relay.stats.delivered[d.direction.value] += 1
            self.relay.stats.lateness_s.append(self.loop.time() - d.due_at)
        except Exception as exc:  # the target already went away; its reader will notice
            log.debug("%s: delivery %s #%d dropped: %r", self.path, d.direction.value, d.index, exc)

    async def _fault(self, fault: LinkFault) -> None:
        self.relay.stats.faults += 1
        self.relay.down_until = max(self.relay.down_until, fault.up_at)
        log.warning("link %s: fault at message %s #%d, %d in flight lost; down for %.3f s",
                    self.path, fault.direction.value, fault.index, fault.lost, fault.up_at - fault.at)
        # the line is down: every channel on it breaks, not only the one that lost a message
        others = [p._close_all(1011, "link fault") for p in self.relay.pipes if p is not self]
        await asyncio.gather(self._close_all(1011, "link fault"), *others)

    async def _close_all(self, code: int, reason: str) -> None:
        if self.tearing_down:
            return
        self.tearing_down = True
        self.core.cut()
        await asyncio.gather(*(ws.close(code, reason) for ws in self.ends.values() if ws is not None),
                             return_exceptions=True)
        self.done.set()


class LinkRelay:
    """Listens for consoles and relays each connection to the robot through a delayed line."""

    def __init__(self, settings: LinkSettings) -> None:
        self.settings = settings
        self.params = settings.params()
        self.stats = LinkStats()
        self.down_until = float("-inf")
        self._seeds = itertools.count()
        self.pipes: set[_Pipe] = set()
        self._server = None
        self.port: int | None = None

    async def start(self) -> None:
        self._server = await serve(
            self._handle, self.settings.host, self.settings.port, process_request=self._process_request,
            compression=None, max_size=MAX_MESSAGE_BYTES, max_queue=None, ping_interval=None, close_timeout=2,
        )
        self.port = next(iter(self._server.sockets)).getsockname()[1]

    async def stop(self) -> None:
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()

    def _process_request(self, connection, request):
        from http import HTTPStatus

        if request.path == "/health":
            body = {"ok": True, "robot": self.settings.robot, "delay_s": self.params.delay_s, **self.stats.as_json()}
            response = connection.respond(HTTPStatus.OK, json.dumps(body) + "\n")
            response.headers["Content-Type"] = "application/json"
            return response
        if request.path not in CHANNEL_PATHS:
            return connection.respond(HTTPStatus.NOT_FOUND, f"no channel {request.path}; valid: {', '.join(CHANNEL_PATHS)}\n")
        if asyncio.get_running_loop().time() < self.down_until:
            return connection.respond(HTTPStatus.SERVICE_UNAVAILABLE, "link down after a fault; retry later\n")
        return None

    async def _handle(self, console) -> None:
        path = console.request.path
        url = self.settings.robot.rstrip("/") + path
        params = self.params.model_copy(update={"seed": self.params.seed + next(self._seeds)})
        pipe = _Pipe(self, console, None, LinkCore(params), path)
        # the console's messages enter the line from the moment they arrive, even while the robot
        # side is still being connected: their delay runs from their arrival
        up_reader = asyncio.create_task(pipe.read(console, Direction.UP))
        # the robot's credential passes through as the console presented it (never logged)
        door = console.request.headers.get(credential.HEADER)
        try:
            robot = await connect(url, compression=None, max_size=MAX_MESSAGE_BYTES, max_queue=None,
                                  ping_interval=None, open_timeout=5, close_timeout=2,
                                  additional_headers={credential.HEADER: door} if door is not None else None)
        except InvalidStatus as exc:  # the robot refused the upgrade: its reason goes back to the console
            self.stats.robot_refused += 1
            reason = _refusal_reason(exc)
            log.warning("link %s: the robot refused the connection: %s", path, reason)
            pipe.tearing_down = True
            up_reader.cancel()
            await asyncio.gather(up_reader, return_exceptions=True)
            await console.close(REFUSED_CLOSE_CODE, reason)
            return
        except Exception as exc:
            self.stats.robot_unreachable += 1
            log.warning("link %s: robot unreachable at %s: %s", path, url, exc)
            pipe.tearing_down = True
            up_reader.cancel()
            await asyncio.gather(up_reader, return_exceptions=True)
            await console.close(1011, "robot unreachable")
            return
        pipe.ends[Direction.UP] = robot
        self.stats.connections += 1
        self.stats.open += 1
        log.info("link %s: console %s joined to %s", path, console.remote_address, url)
        tasks = [up_reader, asyncio.create_task(pipe.read(robot, Direction.DOWN)), asyncio.create_task(pipe.run_timer())]
        self.pipes.add(pipe)
        try:
            await pipe.done.wait()
        finally:
            pipe.tearing_down = True
            self.pipes.discard(pipe)
            for t in tasks:
                t.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            await asyncio.gather(console.close(), robot.close(), return_exceptions=True)
            self.stats.open -= 1
            log.info("link %s: connection closed", path)


REFUSED_CLOSE_CODE = 1008
"""Close code (policy violation) of a console connection the robot refused; the reason follows."""


def _refusal_reason(exc: InvalidStatus) -> str:
    """The robot's one-line reason for refusing an upgrade, cut to what a close frame carries."""
    body = exc.response.body or b""
    text = body.decode("utf-8", "replace").strip().splitlines()[0] if body.strip() else ""
    reason = f"robot refused: {text}" if text else f"robot refused: HTTP {exc.response.status_code}"
    data = reason.encode()[:123]  # a close reason is at most 123 bytes
    return data.decode("utf-8", "ignore")


class _SchedAttr(ctypes.Structure):
    _fields_ = [
        ("size", ctypes.c_uint32), ("sched_policy", ctypes.c_uint32), ("sched_flags", ctypes.c_uint64),
        ("sched_nice", ctypes.c_int32), ("sched_priority", ctypes.c_uint32), ("sched_runtime", ctypes.c_uint64),
        ("sched_deadline", ctypes.c_uint64), ("sched_period", ctypes.c_uint64),
    ]


_SYS_SCHED_SETATTR = {"x86_64": 314, "aarch64": 274}
SHORT_SLICE_NS = 300_000


def request_short_slice() -> bool:
    """Ask Linux for a short scheduler slice (EEVDF, kernel 6.12+): a best-effort latency hint.

    The relay runs in bursts of microseconds and must wake on time; on a busy machine a waking
    task with the default slice often waits for a CPU-bound neighbour's slice to end (several ms).
    A shorter slice gives its wake-ups an earlier deadline, so they preempt sooner. Same policy,
    same nice value; where the call does not exist nothing changes. Measured on the 2-core test
    machine under a load of 5: delay-error p99 mostly under 5 ms with it, mostly over without.
    """
    number = _SYS_SCHED_SETATTR.get(platform.machine())
    if sys.platform != "linux" or number is None:
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        attr = _SchedAttr(size=ctypes.sizeof(_SchedAttr), sched_policy=0, sched_nice=os.nice(0),
                          sched_runtime=SHORT_SLICE_NS)
        ok = libc.syscall(number, 0, ctypes.byref(attr), 0) == 0
    except (OSError, AttributeError):
        ok = False
    log.debug("short scheduler slice %s", "set" if ok else "not available")
    return ok


async def serve_link(settings: LinkSettings, on_ready: Callable[[int], None] | None = None) -> None:
    """Run the relay until SIGINT or SIGTERM."""
    request_short_slice()
    relay = LinkRelay(settings)
    await relay.start()
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    mark("link", "listening")
    if on_ready is not None:
        on_ready(relay.port)
    try:
        await stop.wait()
    finally:
        await relay.stop()
