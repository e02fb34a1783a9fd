"""The sedimentation console (``teleprog up --sedimentation``): the live many-body scene of
thesis chapter 5 in the browser, with no robot and no link.

``create_sedimentation_app(settings)`` builds a FastAPI app whose lifespan starts the
simulation (``server.sedimentation.runner.SedimentationRunner``), starts viser on a private loopback
port, and builds the view (``webui.sedimentation``); the page is served under
``settings.viser_prefix`` by the same relay as the robot console (``server.viser_host``).
API: ``GET /api/health``, ``GET``/``PUT /api/sedimentation``; OpenAPI docs at ``/docs``.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass
from typing import Literal

from fastapi import FastAPI, HTTPException
from fastapi.responses import RedirectResponse
from pydantic import BaseModel

from server.api_docs import add_offline_docs
from server.http_errors import add_error_handler
from server.sedimentation.runner import (
    SedimentationChange,
    SedimentationRunner,
    SedimentationSettings,
    SedimentationState,
)
from server.settings import ConsoleSettings
from server.viser_host import add_viser_routes, start_viser

log = logging.getLogger(__name__)


class SedimentationHealthOut(BaseModel):
    status: Literal["ok"]
    mode: Literal["sedimentation"]


@dataclass
class SedimentationConsole:
    """What the lifespan builds and the endpoints use."""

    settings: ConsoleSettings
    runner: SedimentationRunner
    viser_port: int


def runner_from_settings(settings: ConsoleSettings) -> SedimentationRunner:
    """The runner with the settings' starting values (raises InputError on bad ones)."""
    start = SedimentationSettings(
        method=settings.sedimentation_method, n=settings.sedimentation_n, speed=settings.sedimentation_speed,
        kind=settings.sedimentation_kind, density=settings.sedimentation_density,
    )
    return SedimentationRunner(
        start, steps_hz=settings.sedimentation_steps_hz, draw_hz=settings.sedimentation_draw_hz,
        max_n=settings.sedimentation_max_n,
    )


def create_sedimentation_app(settings: ConsoleSettings | None = None, *, build_page: bool = True) -> FastAPI:
    """The sedimentation app; ``build_page=False`` runs the simulation and API without viser."""
    settings = settings or ConsoleSettings(sedimentation=True)
    runner = runner_from_settings(settings)  # bad starting values fail here, before serving
    holder: dict[str, SedimentationConsole] = {}

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        viser_server = start_viser() if build_page else None
        try:
            if viser_server is not None:
                from webui.sedimentation import build_sedimentation_view

                build_sedimentation_view(viser_server, runner)
            runner.start()
            holder["state"] = SedimentationConsole(settings, runner, viser_server.get_port() if viser_server else 0)
            app.state.sedimentation = holder["state"]
            log.info("sedimentation view running (%s)", runner.settings)
            yield
        finally:
            runner.stop()
            if viser_server is not None:
                viser_server.stop()

    app = FastAPI(
        title="teleprog sedimentation view",
        description=(
            "Many-body collision detection (thesis chapter 5) live: a particle-sedimentation scene stepped "
            "frame by frame, its overlapping sphere pairs found by the chosen method, the detection FPS measured."
        ),
        version="0.1.0",
        lifespan=lifespan,
        docs_url=None,
        redoc_url=None,
    )

    add_error_handler(app)
    add_offline_docs(app)

    @app.get("/", include_in_schema=False)
    def index() -> RedirectResponse:
        return RedirectResponse(settings.viser_prefix + "/")

    @app.get("/api/health", response_model=SedimentationHealthOut, tags=["sedimentation"])
    def health() -> SedimentationHealthOut:
        return SedimentationHealthOut(status="ok", mode="sedimentation")

    @app.get("/api/sedimentation", response_model=SedimentationState, tags=["sedimentation"])
    def get_state() -> SedimentationState:
        """Current method, N, SPEED, scene kind, detection FPS, pairs and frame number."""
        return runner.state()

    @app.put("/api/sedimentation", response_model=SedimentationState, tags=["sedimentation"],
             responses={400: {"description": "a value out of range or an unknown method or kind"}})
    def put_state(change: SedimentationChange) -> SedimentationState:
        """Change settings; fields left out stay. Applied between two frames."""
        return runner.update(**change.model_dump(exclude_none=True))

    def viser_port() -> int:
        if "state" not in holder or not holder["state"].viser_port:
            raise HTTPException(503, "the 3D scene is not running")
        return holder["state"].viser_port

    add_viser_routes(app, viser_port, prefix=settings.viser_prefix)
    return app
