"""Whole-session endpoints: snapshot, control lock, regime override, display mode."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from server.api.deps import ClientDep, SessionDep
from server.api_models import ApiIn
from server.console import (
    Caller,
    ControlAskGrant,
    ControlGrant,
    ControlView,
    DisplayMode,
    Regime,
    RegimeView,
    SessionSnapshot,
)
from shared.errors import InputError

router = APIRouter(prefix="/api", tags=["session"])


class RegimeIn(ApiIn):
    regime: Regime | None = Field(description="force this regime; null follows the control zone again")


class DisplayIn(ApiIn):
    mode: DisplayMode


class DisplayOut(BaseModel):
    display: DisplayMode


@router.get("/session", response_model=SessionSnapshot)
def snapshot(session: SessionDep) -> SessionSnapshot:
    """Everything the page shows, at once."""
    return session.snapshot()


def named(client: Caller, what: str) -> Caller:
    """The caller, refused (400) unless it names itself: control goes to a name people can read."""
    if client.name is None:
        raise InputError(f"name yourself with the X-Teleprog-Client header to {what}")
    return client


@router.get("/control", response_model=ControlView)
def control(session: SessionDep) -> ControlView:
    return session.control.view()


@router.post("/control/request", response_model=ControlGrant)
def request_control(session: SessionDep, client: ClientDep) -> ControlGrant:
    """Take the control lock (name yourself with X-Teleprog-Client). The answer holds the token:
    present it as X-Teleprog-Token on every call that changes state, and to release. 409 while
    another holds control (take over explicitly with ``/api/control/takeover``)."""
    return session.control.request(named(client, "take control"))


@router.post("/control/takeover", response_model=ControlGrant)
def takeover_control(session: SessionDep, client: ClientDep) -> ControlGrant:
    """Take the control lock from whoever holds it; logged, and the former holder sees it (a
    notice and a control event on ``/api/events``, ``last_takeover`` in ``GET /api/control``)."""
    return session.control.takeover(named(client, "take over control"))


@router.post("/control/release", response_model=ControlView)
def release_control(session: SessionDep, client: ClientDep) -> ControlView:
    """Give the lock back; needs the holder's token (X-Teleprog-Token)."""
    return session.control.release(client)


@router.post("/control/ask", response_model=ControlAskGrant)
def ask_control(session: SessionDep, client: ClientDep) -> ControlAskGrant:
    """Ask the holder for control (name yourself with X-Teleprog-Client): every page shows the
    request; the holder hands over or refuses, and if it says nothing for the console's hand-over
    timeout (``asked.passes_at``) control passes to you. The answer's token is yours to present
    once ``GET /api/control`` names you the holder. Nobody holding control: taken at once. 409 while
    another client's request waits."""
    return session.control.ask(named(client, "ask for control"))


@router.post("/control/handover", response_model=ControlView)
def hand_over_control(session: SessionDep, client: ClientDep) -> ControlView:
    """The holder (X-Teleprog-Token) hands control to the client that asked for it."""
    return session.control.hand_over(client)


@router.post("/control/refuse", response_model=ControlView)
def refuse_control(session: SessionDep, client: ClientDep) -> ControlView:
    """The holder (X-Teleprog-Token) refuses the pending request and keeps control."""
    return session.control.refuse(client)


@router.get("/regime", response_model=RegimeView)
def regime(session: SessionDep) -> RegimeView:
    return session.modes.regime_view()


@router.put("/regime", response_model=RegimeView)
def set_regime(body: RegimeIn, session: SessionDep, client: ClientDep) -> RegimeView:
    """Override the regime the control zone calls for (§4.2.1), or follow the zone again."""
    return session.modes.set_regime_override(body.regime, client=client)


@router.get("/display", response_model=DisplayOut)
def display(session: SessionDep) -> DisplayOut:
    return DisplayOut(display=session.modes.display)


@router.put("/display", response_model=DisplayOut)
def set_display(body: DisplayIn, session: SessionDep, client: ClientDep) -> DisplayOut:
    """Teleprogramming, task preview or telepresence (§4.3.7)."""
    return DisplayOut(display=session.modes.set_display_mode(body.mode, client=client))
