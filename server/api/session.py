"""Whole-session endpoints: snapshot, control lock, regime override, display mode."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException
from pydantic import BaseModel, Field

from server.api.deps import ClientDep, SessionDep
from server.console_models import ControlView, DisplayMode, Regime, RegimeView, SessionSnapshot

router = APIRouter(prefix="/api", tags=["session"])


class RegimeIn(BaseModel):
    regime: Regime | None = Field(description="force this regime; null follows the control zone again")


class DisplayIn(BaseModel):
    mode: DisplayMode


class DisplayOut(BaseModel):
    display: DisplayMode


@router.get("/session", response_model=SessionSnapshot)
def snapshot(session: SessionDep) -> SessionSnapshot:
    """Everything the page shows, at once."""
    return session.snapshot()


@router.get("/control", response_model=ControlView)
def control(session: SessionDep) -> ControlView:
    return session.control_view()


@router.post("/control/request", response_model=ControlView)
def request_control(session: SessionDep, client: ClientDep) -> ControlView:
    """Take the control lock (needs the X-Teleprog-Client header); 409 while another holds it."""
    if client is None:
        raise HTTPException(400, "name yourself with the X-Teleprog-Client header to take control")
    return session.request_control(client)


@router.post("/control/release", response_model=ControlView)
def release_control(session: SessionDep, client: ClientDep) -> ControlView:
    if client is None:
        raise HTTPException(400, "name yourself with the X-Teleprog-Client header to release control")
    return session.release_control(client)


@router.get("/regime", response_model=RegimeView)
def regime(session: SessionDep) -> RegimeView:
    return session.regime_view()


@router.put("/regime", response_model=RegimeView)
def set_regime(body: RegimeIn, session: SessionDep, client: ClientDep) -> RegimeView:
    """Override the regime the control zone calls for (§4.2.1), or follow the zone again."""
    return session.set_regime_override(body.regime, client=client)


@router.get("/display", response_model=DisplayOut)
def display(session: SessionDep) -> DisplayOut:
    return DisplayOut(display=session.display_mode)


@router.put("/display", response_model=DisplayOut)
def set_display(body: DisplayIn, session: SessionDep, client: ClientDep) -> DisplayOut:
    """Teleprogramming, task preview or telepresence (§4.3.7)."""
    return DisplayOut(display=session.set_display_mode(body.mode, client=client))
