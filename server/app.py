"""The console's FastAPI app: the API for headless clients and the host of the 3D page.

``create_app(settings)`` builds the app; its lifespan loads the cell, creates the session,
starts viser on a private loopback port, and builds the scene and panels. The page is served
under ``settings.viser_prefix`` by relaying viser's WebSocket, so the operator opens one URL.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass

import numpy as np
from fastapi import FastAPI, HTTPException, Request
from fastapi.responses import RedirectResponse

from server.api_models import HealthOut, JogJointIn, JogToolIn, SetJointsIn, StateOut
from server.session import Session, VirtualState
from server.settings import ConsoleSettings
from server.viser_host import add_viser_routes, start_viser
from shared.cells.loader import load_cell
from shared.errors import InputError, TeleprogError

log = logging.getLogger(__name__)


@dataclass
class ConsoleState:
    """What the lifespan builds and the endpoints use (no module-level globals)."""

    settings: ConsoleSettings
    session: Session
    viser_port: int


def _state_out(state: VirtualState) -> StateOut:
    return StateOut.from_state(state)


def create_app(settings: ConsoleSettings | None = None) -> FastAPI:
    settings = settings or ConsoleSettings()
    cell = load_cell(settings.cell)  # fail before serving anything if the cell is broken
    holder: dict[str, ConsoleState] = {}

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        from webui.panels import DrivePanel
        from webui.scene import CellScene

        session = Session(cell)
        viser_server = start_viser()
        scene = CellScene(viser_server, session)
        DrivePanel(viser_server, session, scene)
        holder["state"] = ConsoleState(settings, session, viser_server.get_port())
        app.state.console = holder["state"]
        log.info("cell %s loaded; 3D scene on private port %d", cell.name, viser_server.get_port())
        try:
            yield
        finally:
            viser_server.stop()

    app = FastAPI(
        title="teleprog console",
        description="Teleprogramming console: drive the virtual robot, program, preview, submit, monitor.",
        version="0.1.0",
        lifespan=lifespan,
    )

    def console(request: Request) -> ConsoleState:
        return request.app.state.console

    @app.exception_handler(TeleprogError)
    async def _teleprog_error(request: Request, exc: TeleprogError):  # noqa: ANN202
        from fastapi.responses import JSONResponse

        status = 400 if isinstance(exc, InputError) else 422
        return JSONResponse({"error": type(exc).__name__, "detail": str(exc)}, status_code=status)

    @app.get("/", include_in_schema=False)
    def index() -> RedirectResponse:
        return RedirectResponse(settings.viser_prefix + "/")

    @app.get("/api/health", response_model=HealthOut)
    def health(request: Request) -> HealthOut:
        c = console(request)
        return HealthOut(status="ok", cell=c.session.cell.name, robot=c.session.robot.name)

    @app.get("/api/state", response_model=StateOut)
    def get_state(request: Request) -> StateOut:
        return _state_out(console(request).session.state)

    @app.put("/api/robot/joints", response_model=StateOut)
    def set_joints(body: SetJointsIn, request: Request) -> StateOut:
        return _state_out(console(request).session.set_q(np.radians(body.deg)))

    @app.post("/api/jog/joint", response_model=StateOut)
    def jog_joint(body: JogJointIn, request: Request) -> StateOut:
        return _state_out(console(request).session.jog_joint(body.joint, float(np.radians(body.delta_deg))))

    @app.post("/api/jog/tool", response_model=StateOut)
    def jog_tool(body: JogToolIn, request: Request) -> StateOut:
        scale = 1e-3 if body.motion == "translate" else np.pi / 180.0
        return _state_out(
            console(request).session.jog_tool(
                frame=body.frame, constraint=body.constraint, motion=body.motion,
                displacement=np.array(body.displacement) * scale,
            )
        )

    add_viser_routes(app, lambda: holder["state"].viser_port if "state" in holder else _no_scene(), prefix=settings.viser_prefix)
    return app


def _no_scene() -> int:
    raise HTTPException(503, "the 3D scene is not running yet")
