"""The replay console (``teleprog replay FILE``): a recorded session, read-only, in the browser.

``create_replay_app(path, settings)`` reads the recording before serving (a bad file fails as one
line), and its lifespan starts viser on a private loopback port and builds the replay page
(``webui.replay``), served under ``settings.viser_prefix`` by the same relay as the console.
The API drives the same playhead as the page: ``GET /api/replay``, ``GET /api/replay/marks``,
``POST /api/replay/seek|play|pause|step|open``, and ``GET /api/sessions`` lists the recordings of
the folder (the recording's own, or ``--dir``). ``open`` takes names inside that folder only (and
the command line's own file by its name): a path leading out, a FIFO or a device is refused, and
no refusal quotes a file's bytes. Nothing here reaches a robot.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Literal

from fastapi import FastAPI, HTTPException, Request
from fastapi.responses import RedirectResponse
from pydantic import BaseModel, Field

from server.api import recordings
from server.api.recordings import RecordingsSource
from server.api_docs import add_offline_docs
from server.http_errors import add_error_handler
from server.replay.player import MarkOut, ReplayPlayer, ReplayView, open_replay
from server.settings import ConsoleSettings
from server.viser_host import add_viser_routes, start_viser

log = logging.getLogger(__name__)


class ReplayHealthOut(BaseModel):
    status: Literal["ok"]
    mode: Literal["replay"]
    file: str


class SeekIn(BaseModel):
    t_s: float = Field(description="s from the recording's start (clamped to it)")


class StepIn(BaseModel):
    direction: Literal["next", "previous"] = "next"


class PlayIn(BaseModel):
    speed: float | None = Field(None, description="times real time (default: as before, 1 at first)")


class OpenIn(BaseModel):
    name: str = Field(max_length=4096, description="a recording's file name in the folder GET /api/sessions lists "
                      "(a path must lead into that folder; the file named on the command line opens by its name)")


def create_replay_app(path: str | Path, settings: ConsoleSettings | None = None, *, folder: Path | None = None,
                      build_page: bool = True) -> FastAPI:
    settings = settings or ConsoleSettings()
    opened = open_replay(path)  # a bad file fails here, before anything is served
    folder = Path(folder) if folder is not None else opened.path.resolve().parent
    holder: dict[str, object] = {}

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        player = ReplayPlayer(opened, folder)
        viser_server = start_viser() if build_page else None
        try:
            if viser_server is not None:
                from webui.replay import build_replay_page

                build_replay_page(viser_server, player)
            holder["viser_port"] = viser_server.get_port() if viser_server is not None else 0
            app.state.player = player
            app.state.recordings = RecordingsSource(folder)
            log.info("replaying %s (%.1f s)", opened.path, opened.timeline.duration_s)
            yield
        finally:
            player.close()
            if viser_server is not None:
                viser_server.stop()

    app = FastAPI(
        title="teleprog replay",
        description="A recorded console session, read-only: the timeline, what the console showed at each moment, "
        "and each submitted range's plan against what the robot reported.",
        version="0.1.0", lifespan=lifespan, docs_url=None, redoc_url=None,
    )
    add_error_handler(app)
    add_offline_docs(app)

    def player_of(request: Request) -> ReplayPlayer:
        player = getattr(request.app.state, "player", None)
        if player is None:
            raise HTTPException(503, "the replay is not running yet")
        return player

    @app.get("/", include_in_schema=False)
    def index() -> RedirectResponse:
        return RedirectResponse(settings.viser_prefix + "/")

    @app.get("/api/health", response_model=ReplayHealthOut, tags=["replay"])
    def health(request: Request) -> ReplayHealthOut:
        return ReplayHealthOut(status="ok", mode="replay", file=str(player_of(request).opened.path))

    @app.get("/api/replay", response_model=ReplayView, tags=["replay"])
    def get_replay(request: Request) -> ReplayView:
        """The playhead and what the console showed there."""
        return player_of(request).view()

    @app.get("/api/replay/marks", response_model=list[MarkOut], tags=["replay"])
    def get_marks(request: Request) -> list[MarkOut]:
        """The moments the step buttons go between."""
        return player_of(request).marks()

    @app.post("/api/replay/seek", response_model=ReplayView, tags=["replay"])
    def seek(body: SeekIn, request: Request) -> ReplayView:
        player = player_of(request)
        player.seek(body.t_s)
        return player.view()

    @app.post("/api/replay/step", response_model=ReplayView, tags=["replay"])
    def step(body: StepIn, request: Request) -> ReplayView:
        player = player_of(request)
        player.step(1 if body.direction == "next" else -1)
        return player.view()

    @app.post("/api/replay/play", response_model=ReplayView, tags=["replay"])
    def play(body: PlayIn, request: Request) -> ReplayView:
        player = player_of(request)
        player.play(body.speed)
        return player.view()

    @app.post("/api/replay/pause", response_model=ReplayView, tags=["replay"])
    def pause(request: Request) -> ReplayView:
        player = player_of(request)
        player.pause()
        return player.view()

    @app.post("/api/replay/open", response_model=ReplayView, tags=["replay"],
              responses={400: {"description": "a name outside the replay's folder, not a regular file, not a "
                                               "recording, damaged where the session starts, or its cell cannot be loaded"}})
    def open_recording(body: OpenIn, request: Request) -> ReplayView:
        player = player_of(request)
        player.open(body.name)
        return player.view()

    app.include_router(recordings.router)
    add_viser_routes(app, lambda: holder["viser_port"] if "viser_port" in holder else _no_scene(),
                     prefix=settings.viser_prefix, send_intervals_ms=settings.page_send_intervals_ms())
    return app


def _no_scene() -> int:
    raise HTTPException(503, "the 3D scene is not running yet")
