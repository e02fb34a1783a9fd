"""The preview player (§4.3.7 task preview): begin a range, play, pause, step, seek, end; the
preview speed; "Preview and submit" (preview a range at that speed, send it if it ends without
warnings)."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter
from pydantic import Field

from server.api.deps import ClientDep, SessionDep
from server.api_models import MAX_COUNT, MAX_TIME_S, ApiIn
from server.console import PreviewAndSubmitView, PreviewView

router = APIRouter(prefix="/api/preview", tags=["preview"])


class RangeIn(ApiIn):
    start: int = Field(0, ge=0, le=MAX_COUNT, description="first statement, 0-based")
    stop: int = Field(ge=0, le=MAX_COUNT, description="one past the last statement")


class PlayIn(ApiIn):
    rate: float | None = Field(None, gt=0, le=100, description="x real time; default: the preview speed")


class SpeedIn(ApiIn):
    speed: float | Literal["instant"] = Field(
        description="plan seconds per clock second, in (0, 100], or 'instant' (stand at the end at once)"
    )


class SeekIn(ApiIn):
    t: float = Field(ge=-MAX_TIME_S, le=MAX_TIME_S, description="s from the range's start")


class StepIn(ApiIn):
    statements: int = Field(1, ge=-MAX_COUNT, le=MAX_COUNT, description="+n: to the end of the n-th statement ahead; -n: back")


@router.get("", response_model=PreviewView)
def get_preview(session: SessionDep) -> PreviewView:
    return session.preview.view()


@router.post("/begin", response_model=PreviewView)
def begin(body: RangeIn, session: SessionDep, client: ClientDep) -> PreviewView:
    return session.preview.begin(body.start, body.stop, client=client)


@router.post("/play", response_model=PreviewView)
def play(session: SessionDep, client: ClientDep, body: PlayIn | None = None) -> PreviewView:
    return session.preview.play((body or PlayIn()).rate, client=client)


@router.post("/pause", response_model=PreviewView)
def pause(session: SessionDep, client: ClientDep) -> PreviewView:
    return session.preview.pause(client=client)


@router.post("/seek", response_model=PreviewView)
def seek(body: SeekIn, session: SessionDep, client: ClientDep) -> PreviewView:
    return session.preview.seek(body.t, client=client)


@router.post("/step", response_model=PreviewView)
def step(session: SessionDep, client: ClientDep, body: StepIn | None = None) -> PreviewView:
    return session.preview.step((body or StepIn()).statements, client=client)


@router.post("/end", response_model=PreviewView)
def end(session: SessionDep, client: ClientDep) -> PreviewView:
    return session.preview.end(client=client)


@router.post("/speed", response_model=PreviewView)
def speed(body: SpeedIn, session: SessionDep, client: ClientDep) -> PreviewView:
    """Set the preview speed for play and for preview-and-submit."""
    return session.preview.set_speed(body.speed, client=client)


@router.post("/submit", response_model=PreviewAndSubmitView)
def preview_and_submit(body: RangeIn, session: SessionDep, client: ClientDep) -> PreviewAndSubmitView:
    """Preview statements[start:stop] at the preview speed; if it ends without warnings, submit
    them (at once for 'instant', else when the player reaches the end). Refused before
    previewing when they could not be sent anyway."""
    return session.preview.preview_and_submit(body.start, body.stop, client=client)
