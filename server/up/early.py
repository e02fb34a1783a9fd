"""What ``teleprog up`` does before the console's heavy imports: start the telerobot and the link,
and open the robot connection, so the hello crosses the delayed link while the console imports
its web stack and builds its page.

Order (``start_early``, called by the ``up`` command before it imports ``server.up.run``):

1. the settings from the flags (a bad value is a one-line error before anything starts);
2. the telerobot and the link spawned (``server.up.stack``), without waiting; then the cell
   loaded (a broken one stops them again and is a one-line error: the robot, started with
   ``--listen-first``, loads it only after it listens);
3. a ``robot-io`` thread with an event loop of its own (uvloop's, ``new_loop``): it waits until both children listen,
   then starts the ``RobotClient`` on that loop, which says hello at once. The client stays on
   this thread for the console's lifetime (the session submits to it with
   ``run_coroutine_threadsafe`` on ``EarlyRobot.loop``, as it does on any loop).

The console's main thread meanwhile imports the app; ``EarlyRobot.wait_children`` then gives it
the children (or raises the ``InputError`` saying why one did not start). Only the standard
library, uvloop, settings and the robot client are imported here.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from server.settings import ConsoleSettings
from server.up.stack import Child, spawn_robot_and_link, stop_child
from shared.errors import TeleprogError
from shared.startup_trace import mark

log = logging.getLogger(__name__)


def settings_from_args(args: argparse.Namespace) -> ConsoleSettings:
    get = lambda name: getattr(args, name, None)  # noqa: E731 - flags absent from older callers
    return ConsoleSettings().with_overrides(
        port=get("port"), host=get("host"), cell=get("cell"), delay_ms=get("delay_ms"), robot_url=get("robot_url"),
        no_robot=True if get("no_robot") else None, robot_port=get("robot_port"), link_port=get("link_port"),
        sedimentation=True if get("sedimentation") else None, restart_children=False if get("no_restart") else None,
        record=False if get("no_record") else None, record_dir=get("record"),
        fault_injection=True if get("fault_injection") else None, robot_credential_file=get("robot_credential_file"),
        strict_editing=True if get("strict_editing") else None, handover_timeout_s=get("handover_timeout_s"),
    )


def robot_credential(settings: ConsoleSettings, *, make: bool) -> str | None:
    """The credential the console presents to its robot: the one set (``TELEPROG_ROBOT_CREDENTIAL``),
    else the one in ``robot_credential_file``, else (``make``: the robot ``teleprog up`` starts) a
    new one; None when there is none to present (the robot will refuse and say why)."""
    from shared.wire.credential import checked, new_credential, read_credential_file

    if settings.robot_credential is not None:
        return checked(settings.robot_credential.get_secret_value(), "TELEPROG_ROBOT_CREDENTIAL")
    if settings.robot_credential_file is not None:
        return read_credential_file(settings.robot_credential_file.expanduser())
    return new_credential() if make else None


def new_loop() -> asyncio.AbstractEventLoop:
    """The robot-io thread's loop: uvloop's (a dependency; uvicorn runs the console's own on it)
    where it imports, else asyncio's. Telemetry wakes this loop 50 times a second; in uvloop a
    wake and a frame's read cost about half the CPU of asyncio's selector loop."""
    try:
        import uvloop
    except ImportError:  # pragma: no cover - uvloop is a dependency; a platform without it
        return asyncio.new_event_loop()
    return uvloop.new_event_loop()


class EarlyRobot:
    """The robot client on its own thread and loop, connecting as soon as ``children`` listen."""

    def __init__(self, url: str, settings: ConsoleSettings, children: list[Child], credential: str | None = None) -> None:
        self.url = url
        self._credential = credential  # presented to the robot; never logged
        self.settings = settings
        self.children = children
        self.loop = new_loop()
        self.client = None  # the RobotClient, once the thread made it
        self._children_ready = threading.Event()
        self._client_made = threading.Event()
        self._error: TeleprogError | None = None
        self._lock = threading.Lock()
        self._on_connected: list[Callable[[float], None]] = []
        self._handshake_s: float | None = None
        self._stop = asyncio.Event()  # bound to self.loop on first use there
        self._thread = threading.Thread(target=self._run, name="robot-io", daemon=True)

    def start(self) -> "EarlyRobot":
        self._thread.start()
        return self

    # -- the main thread ---------------------------------------------------------------------------
    def wait_children(self) -> list[Child]:
        """Block until both children listen; raises what went wrong with one of them."""
        self._children_ready.wait()
        if self._error is not None:
            raise self._error
        return self.children

    def wait_client(self):
        """The ``RobotClient`` (made on the robot-io thread right after the children listen)."""
        self.wait_children()
        self._client_made.wait()
        return self.client

    def when_connected(self, callback: Callable[[float], None]) -> None:
        """``callback(handshake_s)`` once the first welcome came (at once if it already did)."""
        with self._lock:
            if self._handshake_s is None:
                self._on_connected.append(callback)
                return
            handshake = self._handshake_s
        callback(handshake)

    def close(self, timeout: float = 5.0) -> None:
        """Close the client and end the thread (from any thread but robot-io)."""
        try:
            self.loop.call_soon_threadsafe(self._stop.set)
        except RuntimeError:  # the loop is closed: the thread ended already (a child failed)
            pass
        self._thread.join(timeout)

    # -- the robot-io thread -------------------------------------------------------------------
    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        try:
            self.loop.run_until_complete(self._main())
        finally:
            self.loop.close()

    async def _main(self) -> None:
        from server.robot_client import RobotClient  # while the children start

        try:
            for child in self.children:
                child.wait_ready(self.settings.child_start_timeout_s)  # blocks this thread only
        except TeleprogError as exc:
            self._error = exc
            return
        finally:
            self._children_ready.set()
        mark("console", "children listening")

        from server.up.identity import console_identity

        identity = console_identity(self.settings.record_dir / self.settings.identity_file)
        client = self.client = RobotClient(self.url, client_id=identity, silence_limit_s=self.settings.silence_limit_s,
                                           credential=self._credential, kept_identity=True)
        self._client_made.set()
        connect = asyncio.create_task(self._connect(client), name="robot-connect")
        try:
            await self._stop.wait()
        finally:
            connect.cancel()
            await asyncio.gather(connect, return_exceptions=True)
            await client.close()

    async def _connect(self, client) -> None:
        await client.start(timeout=1e9)  # keeps trying; submissions queue meanwhile
        handshake = client.handshake_s or 0.0
        log.info("robot at %s connected", self.url)
        mark("console", f"robot connected (handshake {handshake:.3f} s)")
        with self._lock:
            self._handshake_s = handshake
            callbacks, self._on_connected = self._on_connected, []
        for callback in callbacks:
            callback(handshake)


@dataclass
class EarlyStart:
    """What ``start_early`` began: the settings, the children (empty when none were started)
    and the robot client starting on its thread (None: console only)."""

    settings: ConsoleSettings
    children: list[Child] = field(default_factory=list)
    robot: EarlyRobot | None = None


def start_early(args: argparse.Namespace) -> EarlyStart:
    """Spawn the telerobot and the link and start connecting to them (see the module docstring)."""
    settings = settings_from_args(args)
    if settings.sedimentation or settings.no_robot:
        return EarlyStart(settings)
    if settings.robot_url:
        secret = robot_credential(settings, make=False)
        return EarlyStart(settings, robot=EarlyRobot(settings.robot_url, settings, [], secret).start())
    secret = robot_credential(settings, make=True)  # the robot started here answers to this console alone
    robot, link, link_url = spawn_robot_and_link(
        cell=settings.cell, robot_port=settings.robot_port, link_port=settings.link_port, delay_ms=settings.delay_ms,
        credential=secret, cache_dir=settings.cache_dir,
    )
    mark("console", "children spawned")
    try:
        from shared.cells.loader import load_cell

        load_cell(settings.cell)  # a broken cell fails here, while the children start (--listen-first)
    except BaseException:
        for child in (link, robot):
            stop_child(child)
        raise
    # the console serves once both listen, so its first connection reaches the robot: no
    # retries to log while they start (a child that fails says why, and nothing is served)
    print("teleprog up: waiting for the telerobot and the link to start ...", flush=True)
    settings = settings.model_copy(update={"robot_url": link_url})
    return EarlyStart(settings, [robot, link], EarlyRobot(link_url, settings, [robot, link], secret).start())
