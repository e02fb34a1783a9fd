"""The console's session: one per console process, made of parts with one concern each.

``Session`` wires the parts together and keeps what is truly shared: the control lock, the event
bus and the clocks. Callers use the parts as sub-APIs, the way viser's server exposes
``server.scene`` and ``server.gui``:

* ``session.arm``: the virtual arm (driving, jog rules, held objects, collision and zone);
* ``session.program``: the program desk (editor, automatic generation, files, the start state);
* ``session.preview``: plan, check and play a range of the program;
* ``session.dispatch``: submission, numbered statuses, the robot seam;
* ``session.recovery``: STOP, resume, skip, abort, back away;
* ``session.remote``: telemetry, reported objects, the predicted path, divergence, re-sync;
* ``session.link``: the link's health for the status bar;
* ``session.modes``: the regime and the display mode;
* ``session.readiness``: what Submit needs now, in the regime's words, and whether drags stream;
* ``session.terrain``: ground checks and instrument placement (rover cells);
* ``session.locator``: correcting objects from a camera;
* ``session.control``: the control lock.

Errors: ``shared.errors.InputError`` for malformed input (HTTP 400), ``ConflictError`` /
``RefusedByRule`` when the state forbids an action now (409), other ``TeleprogError`` (a joint
limit, say) 422. Every changing call takes ``client``: a ``Caller`` (name and token), a bare name,
or ``None`` for the page this console serves.
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from server.console.arm import VirtualArm
from server.console.bus import EventBus
from server.console.context import Clock, ConsoleContext, SessionSettings
from server.console.control import ControlLock
from server.console.dispatch import Dispatch
from server.console.events import SessionEvent
from server.console.link_status import LinkStatus
from server.console.locate import Locator
from server.console.modes import Modes
from server.console.previewer import Previewer
from server.console.program_desk import ProgramDesk
from server.console.readiness import Readiness
from server.console.task_commands import TaskCommands
from server.console.task_monitor import TaskMonitor
from server.console.recovery import Recovery
from server.console.remote import RemoteMirror
from server.console.robot_seam import RobotLink
from server.console.terrain_tools import TerrainTools
from server.console.views import Caller, SessionSnapshot
from shared.cells.cell import Cell
from shared.collision import SceneModel
from shared.collision.cell_check import CellCollision
from shared.terrain.ground import GroundChecker


log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CellOffers:
    """What the session's cell offers the page: a terrain with placement, cameras to locate
    objects from, movable objects."""

    terrain: bool
    cameras: tuple[str, ...]
    objects: tuple[str, ...]


class Session:
    """One operator console's parts (see the module docstring)."""

    def __init__(
        self,
        cell: Cell,
        settings: SessionSettings | None = None,
        clock: Clock = time.monotonic,
        scene: SceneModel | None = None,
        wall_clock: Clock = time.time,
    ) -> None:
        """``scene``: the cell's collision model when the caller already built it (immutable;
        seconds to build); ``clock``: monotonic seconds; ``wall_clock``: Unix seconds."""
        self.cell = cell
        self.robot = cell.robot
        self.bus = EventBus()
        ctx = self._ctx = ConsoleContext(cell, settings or SessionSettings(), self.bus, clock, wall_clock)
        self.settings = ctx.settings
        self.clock, self.wall_clock = clock, wall_clock
        self.frames = ctx.frames  # where the named jog frames are (world_T_base, work, the tool point)
        ground = GroundChecker.for_cell(cell)
        collision = CellCollision(cell, scene=scene, ground=ground)
        self.control = ControlLock(ctx)
        self.modes = Modes(ctx, self.control)
        self.terrain = TerrainTools(ctx, ground, self.control)
        self.program = ProgramDesk(ctx, self.control, self.modes)
        self.preview = Previewer(ctx, collision, self.control, self.modes, self.program,
                                 lambda: (self.arm.object_poses(), self.arm.objects.held))
        self.arm = VirtualArm(ctx, collision, self.control, self.modes, self.program, self.preview, self.terrain)
        self.program.objects_at_start = self.arm.task_objects
        self.dispatch = Dispatch(ctx, self.control, self.modes, self.program, self.arm)
        self.remote = RemoteMirror(ctx, self.control, self.program, self.arm, self.dispatch)
        self.link = LinkStatus(ctx, self.dispatch, self.remote)
        self.recovery = Recovery(ctx, self.control, self.program, self.dispatch, self.remote, self.link)
        self.locator = Locator(ctx, self.control, self.program, self.arm)
        # the parts that call each other both ways learn of each other here
        self.program.preview, self.program.dispatch = self.preview, self.dispatch
        self.dispatch.remote, self.dispatch.link = self.remote, self.link
        self.remote.link = self.link
        self.link.recovery = self.recovery
        self.terrain.desk, self.terrain.arm = self.program, self.arm
        self.preview.submit, self.preview.submit_refusal = self.dispatch.submit, self.dispatch.refusal
        self.readiness = Readiness(ctx, self.modes, self.program, self.dispatch, self.preview)
        self.task = TaskMonitor(ctx, preview_source=self._preview_source)
        self.bus.subscribe(self.task.on_event)
        self.task_commands = TaskCommands(ctx, self.control, self.task, self.program, self.arm)
        self._closed = threading.Event()

    def _preview_source(self, stop: int):
        """What the task panel plays for a preview ending at ``stop``: the statements, the
        program's start and the virtual objects (read under the session's lock)."""
        with self._ctx.lock:
            statements = tuple(self.program.editor.state.statements[:stop])
            return statements, self.program.start.q.copy(), self.arm.object_poses(), self.arm.objects.held

    def offers(self) -> CellOffers:
        """What the cell offers (the page builds its panels from this)."""
        cell = self.cell
        return CellOffers(terrain=self.terrain.available, cameras=tuple(cell.cameras), objects=tuple(cell.object_names))

    def subscribe_events(self, listener: Callable[[SessionEvent], None]) -> Callable[[], None]:
        """Call ``listener(event)`` for every ``SessionEvent``; returns a function that unsubscribes."""
        return self.bus.subscribe(listener)

    def snapshot(self) -> SessionSnapshot:
        """Every view at once."""
        with self._ctx.lock:
            return SessionSnapshot(
                cell=self.cell.name, robot=self.robot.name, dof=self.robot.dof, arm=self.arm.view(),
                program=self.program.view(), preview=self.preview.view(), sent=self.dispatch.view(),
                link=self.link.view(), remote=self.remote.view(), predicted=self.remote.predicted_view(),
                collision=self.arm.collision_view(), regime=self.modes.regime_view(), display=self.modes.display,
                divergence=self.remote.divergence_view(), control=self.control.view(),
                readiness=self.readiness.view(),
            )

    def resync(self, *, client: Caller | str | None = None) -> SessionSnapshot:
        """Take the robot's reported state as the virtual arm's and the program's start (§4.2.3)."""
        return self.remote.resync(client=client, snapshot=self.snapshot)

    def attach_robot(self, robot: RobotLink, loop: asyncio.AbstractEventLoop) -> None:
        """Use ``robot`` (a started or starting robot client) on ``loop``; once, at start."""
        self.dispatch.attach(robot, loop)

    def tick(self) -> None:
        """What runs on the console's clock: a playing preview, the link view's timer and a
        request for control waiting on its holder."""
        self.preview.tick()
        self.link.tick()
        self.control.tick()

    def start_clock(self) -> threading.Thread:
        """Tick at the preview's player rate for the console's lifetime, on a thread of its own:
        a tick takes the session's lock, and the web server's loop must never wait for it."""
        period = 1.0 / self.settings.player_rate_hz

        def run() -> None:
            while not self._closed.wait(period):
                try:
                    self.tick()
                except Exception:  # noqa: BLE001 - the clock must go on
                    log.exception("the session's clock tick failed")

        thread = threading.Thread(target=run, name="session-clock", daemon=True)
        thread.start()
        return thread

    def later(self, fn: Callable[..., None], *args: object) -> None:
        """``fn(*args)`` on the console's ``after`` thread: for a caller on the robot client's
        loop, which must not wait for the session's lock."""
        self._ctx.after.post(fn, *args)

    def busy(self) -> bool:
        """Whether another thread holds the session's lock now (a long computation): the web
        server's loop then hands a quick call (a jog) to a worker thread instead of waiting."""
        lock = self._ctx.lock
        if lock.acquire(blocking=False):
            lock.release()
            return False
        return True

    def close(self) -> None:
        """The clock stops; the threads that follow the robot's answers and play ranges end."""
        self._closed.set()
        self._ctx.after.close()
        self.task.close()

    def stall(self, seconds: float) -> bool:
        """Fault injection (``server.api.faults``): a thread holds the session's lock and computes
        for ``seconds``, as a slow plan would. True once it holds the lock (within 5 s)."""
        holding = threading.Event()

        def compute() -> None:
            with self._ctx.lock:
                holding.set()
                end = time.monotonic() + seconds
                n = 0
                while time.monotonic() < end:  # pure Python: it holds the interpreter as a plan does
                    n += sum(i * i for i in range(200))
            log.warning("fault injection: the session's work stalled for %.1f s", seconds)

        threading.Thread(target=compute, name="fault-stall", daemon=True).start()
        return holding.wait(5.0)
