"""The console's FastAPI app: the API for headless clients and the host of the 3D page.

``create_app(settings)`` builds the app; its lifespan loads the cell, creates the session,
connects it to the robot (``settings.robot_url``: the link or a robot, over ``RobotClient``),
starts viser on a private loopback port, and builds the scene and panels. The page is served
under ``settings.viser_prefix`` by relaying viser's WebSocket, so the operator opens one URL.
The API routers live in ``server.api``; OpenAPI docs at ``/docs``.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from fastapi import FastAPI, HTTPException, Request
from fastapi.responses import RedirectResponse

from server.api import include_routers
from server.api.jog_lane import JogLane
from server.api.recordings import RecordingNow, RecordingsSource
from server.trials.service import TrialBatches
from server.api_docs import add_offline_docs
from server.api_models import HealthOut
from server.loop_watch import LoopWatch
from server.console import Session, SessionSettings
from server.http_errors import ERROR_RESPONSES, add_error_handler
from server.recording.recorder import SessionRecorder, record_session
from server.settings import ConsoleSettings
from server.up.early import EarlyRobot, robot_credential
from server.viser_host import add_viser_routes, start_viser
from shared.cells.loader import load_cell
from shared.startup_trace import mark

log = logging.getLogger(__name__)


@dataclass
class ConsoleState:
    """What the lifespan builds and the endpoints use (no module-level globals)."""

    settings: ConsoleSettings
    session: Session
    viser_port: int
    recorder: SessionRecorder | None = None


def _build_page(viser_server, session: Session, trials: TrialBatches) -> None:
    """The viser scene and panels (``webui.console.build_console``)."""
    from webui.console import build_console

    build_console(viser_server, session, trials)


def create_app(
    settings: ConsoleSettings | None = None,
    *,
    build_page: bool = True,
    children: Callable[[], dict[str, str]] | None = None,
    robot: EarlyRobot | None = None,
) -> FastAPI:
    """The console app; ``build_page=False`` serves the API without the 3D page's panels;
    ``children()``: how the processes ``teleprog up`` watches are (shown in the link view);
    ``robot``: a robot client ``teleprog up`` started on its own thread before the app existed
    (``server.up.early``; the caller closes it); without one, the app starts its own the same way
    when ``robot_url`` is set."""
    settings = settings or ConsoleSettings()
    cell = load_cell(settings.cell)  # fail before serving anything if the cell is broken
    holder: dict[str, ConsoleState] = {}
    loop_watch = LoopWatch()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        session = Session(cell, SessionSettings(strict_editing=settings.strict_editing,
                                                 handover_timeout_s=settings.handover_timeout_s))
        if children is not None:
            session.link.watch_children(children)
        recorder = record_session(session, settings, started_link=children is not None)
        tasks: list[asyncio.Task] = []
        own_robot = None  # a robot client this app started itself (closed with it)
        if robot is None and settings.robot_url and not settings.no_robot:
            own_robot = EarlyRobot(settings.robot_url, settings, [], robot_credential(settings, make=False)).start()
        attached = robot or own_robot
        if attached is not None:
            session.attach_robot(attached.wait_client(), attached.loop)
            # the round trip alone; the callback runs on the robot-io thread: the lock is taken elsewhere
            attached.when_connected(lambda seconds: session.later(session.dispatch.note_round_trip, seconds))
        tasks.append(asyncio.create_task(loop_watch.run(), name="loop-watch"))
        session.start_clock()  # its own thread: a tick takes the session's lock, this loop must not wait
        viser_server = start_viser()
        trials = TrialBatches(settings.cell)
        try:
            if build_page:
                _build_page(viser_server, session, trials)
            holder["state"] = ConsoleState(settings, session, viser_server.get_port(), recorder)
            app.state.console = holder["state"]
            app.state.recordings = RecordingsSource(Path(settings.record_dir), lambda: _recording_now(recorder))
            app.state.trials = trials
            log.info("cell %s loaded; 3D scene on private port %d", cell.name, viser_server.get_port())
            mark("console", "page built")
            yield
        finally:
            trials.close()
            session.close()
            for task in tasks:
                task.cancel()
            with suppress(Exception):
                await asyncio.gather(*tasks, return_exceptions=True)
            if own_robot is not None:
                await asyncio.to_thread(own_robot.close)
            if recorder is not None:
                recorder.close()
            viser_server.stop()

    app = FastAPI(
        title="teleprog console",
        description=(
            "Teleprogramming console: drive the virtual robot, program, preview, submit, monitor. "
            "Name the caller with the X-Teleprog-Client header; while a client holds control "
            "(POST /api/control/request returns its token), calls that change state present the token "
            "as X-Teleprog-Token. Events stream on the WebSocket /api/events."
        ),
        version="0.2.0",
        lifespan=lifespan,
        docs_url=None,
        redoc_url=None,
        # the console exports no OpenTelemetry; on, FastAPI asks the global providers whether
        # anyone listens on every request (ignored by FastAPI versions without telemetry)
        telemetry={"tracing": False, "metrics": False, "logs": False},
    )

    add_error_handler(app)
    add_offline_docs(app)
    app.add_middleware(JogLane)  # the jogs' ordinary requests, ahead of FastAPI's routing

    @app.get("/", include_in_schema=False)
    def index() -> RedirectResponse:
        return RedirectResponse(settings.viser_prefix + "/")

    @app.get("/api/health", response_model=HealthOut, response_model_exclude_none=True, tags=["session"],
             responses=ERROR_RESPONSES)
    async def health(request: Request, loop: Literal["true", "reset"] | None = None) -> HealthOut:
        """The console is up; with ``loop``, how late its event loop wakes (``reset``: the window
        starts again after this answer). Answered on the loop itself: a stalled loop answers late."""
        c: ConsoleState = request.app.state.console
        lag = None
        if loop is not None:
            lag = loop_watch.view()
            if loop == "reset":
                loop_watch.reset()
        return HealthOut(status="ok", cell=c.session.cell.name, robot=c.session.robot.name, loop=lag)

    include_routers(app)
    if settings.fault_injection:
        from server.api import faults

        app.include_router(faults.router, responses=ERROR_RESPONSES)
    add_viser_routes(
        app,
        lambda: holder["state"].viser_port if "state" in holder else _no_scene(),
        prefix=settings.viser_prefix,
        send_intervals_ms=settings.page_send_intervals_ms(),
    )
    return app


def _recording_now(recorder: SessionRecorder | None) -> RecordingNow | None:
    if recorder is None:
        return None
    stats = recorder.writer.stats()
    return RecordingNow(path=stats.path, written=stats.written, dropped=stats.dropped, failed=stats.failed)


def _no_scene() -> int:
    raise HTTPException(503, "the 3D scene is not running yet")
