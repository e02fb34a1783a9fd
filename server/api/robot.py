"""Submit and monitor (§4.3.6, §4.4): submit a range, the sent list, STOP/resume/skip/abort,
the link, the remote arm, the predicted path, divergence and re-sync."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException
from pydantic import Field

from server.api.deps import ClientDep, SessionDep
from server.api_models import MAX_COUNT, ApiIn
from server.console import (
    DivergenceView,
    LinkView,
    PredictedPathView,
    RemoteArmView,
    SentListView,
    SessionSnapshot,
)

router = APIRouter(prefix="/api", tags=["robot"])


class SubmitIn(ApiIn):
    start: int = Field(0, ge=0, le=MAX_COUNT)
    stop: int = Field(le=MAX_COUNT, description="one past the last statement to send")


class SkipIn(ApiIn):
    number: int | None = Field(None, ge=1, le=MAX_COUNT, description="robot number; default the one running "
                               f"(at most {MAX_COUNT}: no session numbers more statements)")


@router.post("/submit", response_model=SentListView)
def submit(body: SubmitIn, session: SessionDep, client: ClientDep) -> SentListView:
    """Send statements[start:stop]; they leave the program and join the sent list."""
    return session.dispatch.submit(body.start, body.stop, client=client)


@router.get("/sent", response_model=SentListView)
def sent(session: SessionDep) -> SentListView:
    return session.dispatch.view()


@router.post("/robot/stop", response_model=LinkView)
def stop(session: SessionDep, client: ClientDep) -> LinkView:
    """STOP (anyone may press it)."""
    return session.recovery.stop(client=client)


@router.post("/robot/resume", response_model=LinkView)
def resume(session: SessionDep, client: ClientDep) -> LinkView:
    return session.recovery.resume(client=client)


@router.post("/robot/skip", response_model=LinkView)
def skip(session: SessionDep, client: ClientDep, body: SkipIn | None = None) -> LinkView:
    return session.recovery.skip((body or SkipIn()).number, client=client)


@router.post("/robot/abort", response_model=LinkView)
def abort(session: SessionDep, client: ClientDep) -> LinkView:
    return session.recovery.abort(client=client)


@router.get("/link", response_model=LinkView)
def link(session: SessionDep, client: ClientDep) -> LinkView:
    """The link. ``url``, the robot's address, only to the holder of control (its token); never the credential."""
    return session.link.view(address=session.control.holds(client))


@router.get("/remote", response_model=RemoteArmView)
def remote(session: SessionDep) -> RemoteArmView:
    view = session.remote.view()
    if view is None:
        raise HTTPException(404, "no telemetry from the robot yet")
    return view


@router.get("/predicted", response_model=PredictedPathView)
def predicted(session: SessionDep) -> PredictedPathView:
    return session.remote.predicted_view()


@router.get("/divergence", response_model=DivergenceView)
def divergence(session: SessionDep) -> DivergenceView:
    return session.remote.divergence_view()


@router.post("/resync", response_model=SessionSnapshot)
def resync(session: SessionDep, client: ClientDep) -> SessionSnapshot:
    """Re-sync the virtual arm and held object from telemetry; the program starts there."""
    return session.resync(client=client)
