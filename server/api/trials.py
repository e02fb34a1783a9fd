"""Trials (thesis §4.6) from the running console: ``POST /api/trials`` starts a batch on the
console's cell, ``GET /api/trials/{id}`` reports its progress and, once done, its table and
summary, ``GET /api/trials/{id}/plots/{name}`` serves its plots (``server.trials.service``).

A batch's runs are sessions of their own; they never touch the console's robot, so starting one
needs no control lock. One batch runs at a time, its runs one after the other in a spawned process
(``teleprog trial --workers K`` or a Dask scheduler spreads them out)."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request, Response

from pydantic import ConfigDict, Field

from server.api_models import ApiIn
from server.trials.batch import TrialWorld
from server.trials.runner import MAX_DELAY_MS, TrialKind, TrialRequest
from server.trials.service import TrialBatches, TrialBatchView
from shared.errors import InputError

MAX_API_RUNS = 20  # per mode: the transfer's four modes make 80 runs, about a minute in virtual time

router = APIRouter(prefix="/api", tags=["trials"])


def _batches(request: Request) -> TrialBatches:
    batches = getattr(request.app.state, "trials", None)
    if batches is None:
        raise HTTPException(503, "the console session is not running yet")
    return batches


class TrialIn(ApiIn):
    """A batch from the console: virtual time, at most ``MAX_API_RUNS`` runs of each mode; an
    unknown field (``clock``, ``workers``) is refused, not ignored."""

    model_config = ConfigDict(allow_inf_nan=False, extra="forbid")

    kind: TrialKind
    runs: int = Field(5, ge=1, le=MAX_API_RUNS)
    delay_ms: float = Field(3000.0, ge=0.0, le=MAX_DELAY_MS, description="link delay each way, ms")
    seed: int = Field(0, ge=0, le=10**9, description="run i's world is seeded seed*1000+i")
    modes: tuple[str, ...] | None = Field(None, max_length=8, description="the transfer trial's modes; default all")
    world: TrialWorld = Field(default_factory=TrialWorld)


@router.post("/trials", response_model=TrialBatchView)
def start_trials(body: TrialIn, request: Request) -> TrialBatchView:
    """Start a batch on the console's cell, in virtual time (real-time batches start a whole
    session per run: ``teleprog trial --clock real``). 409 while another batch runs; 422 when the
    cell lacks what the kind needs or a mode is not the kind's."""
    batches = _batches(request)
    trial = TrialRequest(kind=body.kind, runs=body.runs, delay_ms=body.delay_ms, seed=body.seed, clock="virtual",
                         modes=body.modes, world=body.world)
    try:
        return batches.start(trial)
    except InputError as exc:
        raise HTTPException(422, str(exc)) from None


@router.get("/trials/{batch_id}", response_model=TrialBatchView)
def trial_batch(batch_id: int, request: Request) -> TrialBatchView:
    view = _batches(request).view(batch_id)
    if view is None:
        raise HTTPException(404, f"no trial batch {batch_id}")
    return view


@router.get("/trials/{batch_id}/plots/{name}", responses={200: {"content": {"image/png": {}}}})
def trial_plot(batch_id: int, name: str, request: Request) -> Response:
    data = _batches(request).plot(batch_id, name)
    if data is None:
        raise HTTPException(404, f"trial batch {batch_id} has no plot {name!r} (yet)")
    return Response(data, media_type="image/png")
