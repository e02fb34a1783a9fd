"""Fault injection (``TELEPROG_FAULT_INJECTION=1`` or ``teleprog up --fault-injection``; never on
by default): make the console itself misbehave on purpose, so tests and surprise campaigns can
show that what keeps the robot safe does not depend on the console behaving.

``POST /api/faults/stall {"seconds": 5}``: the session's work stalls, as a plan that computes for
seconds does: a thread takes the session's lock and computes (Python, holding the interpreter
between its switches) for ``seconds``. Every call that needs the session waits meanwhile;
heartbeats and STOP must not.
"""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from server.api.deps import SessionDep

router = APIRouter(prefix="/api/faults", tags=["faults"])

MAX_STALL_S = 60.0


class StallIn(BaseModel):
    seconds: float = Field(gt=0.0, le=MAX_STALL_S, description="how long the session's work stalls (s)")


class StallOut(BaseModel):
    seconds: float
    started: bool = Field(description="the stall holds the session's lock now")


@router.post("/stall", response_model=StallOut)
def stall(body: StallIn, session: SessionDep) -> StallOut:
    """Start a stall of the session's work; answers once it holds the session's lock."""
    return StallOut(seconds=body.seconds, started=session.stall(body.seconds))
