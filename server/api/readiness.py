"""What Submit needs now (the regime's rule in words, and how far a range is from it), read
before sending: the same checks ``POST /api/submit`` applies, without sending."""

from __future__ import annotations

from fastapi import APIRouter, Query

from server.api.deps import SessionDep
from server.api_models import MAX_COUNT
from server.console import SubmitReadiness

router = APIRouter(prefix="/api", tags=["robot"])


@router.get("/readiness", response_model=SubmitReadiness)
def readiness(
    session: SessionDep,
    start: int = Query(0, ge=0, le=MAX_COUNT, description="first statement, 0-based"),
    stop: int | None = Query(None, ge=0, le=MAX_COUNT, description="one past the last; default: the whole program"),
) -> SubmitReadiness:
    return session.readiness.view(start, stop)
