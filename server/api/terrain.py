"""The lunar-rover terrain (seed 004): the arm against the ground, the virtual sensors, and
instrument placement at a target (terrain cells only; other cells answer 400)."""

from __future__ import annotations

import numpy as np
from fastapi import APIRouter
from pydantic import Field, model_validator

from server.api.deps import ClientDep, SessionDep
from server.api_models import MAX_COUNT, ApiIn, Millimetres, StateOut
from server.console import PlacementView, ProgramView, TerrainView

router = APIRouter(prefix="/api/terrain", tags=["terrain"])


class SensorsIn(ApiIn):
    show: bool = Field(description="draw the virtual sensors and send their segments with each terrain view")


class PlaceIn(ApiIn):
    """The target: a terrain point, or a ground position whose terrain point is meant."""

    target_mm: tuple[Millimetres, Millimetres, Millimetres] | None = Field(None, description="target point on the terrain, world, mm")
    ground_mm: tuple[Millimetres, Millimetres] | None = Field(None, description="ground position (x, y), world, mm")

    @model_validator(mode="after")
    def _one_target(self) -> "PlaceIn":
        if (self.target_mm is None) == (self.ground_mm is None):
            raise ValueError("give exactly one of target_mm or ground_mm")
        return self


class GotoIn(ApiIn):
    candidate: int = Field(1, ge=1, le=MAX_COUNT, description="placement candidate, 1-based (1: the best)")


@router.get("", response_model=TerrainView)
def terrain(session: SessionDep) -> TerrainView:
    """Exact arm-terrain distance with its witness points, the head's distance, the sensors'
    reading and, on contact, the touching triangles, at the virtual arm's pose."""
    return session.terrain.view()


@router.put("/sensors", response_model=TerrainView)
def sensors(body: SensorsIn, session: SessionDep, client: ClientDep) -> TerrainView:
    return session.terrain.set_sensors(body.show, client=client)


@router.post("/placement", response_model=PlacementView)
def place(body: PlaceIn, session: SessionDep, client: ClientDep) -> PlacementView:
    """Plan the instrument placement at the target: every safe configuration, best first, and
    the statements of the best (insert them with ``POST /api/terrain/placement/insert``)."""
    if body.target_mm is not None:
        return session.terrain.place_instrument(world_p=np.asarray(body.target_mm) * 1e-3, client=client)
    return session.terrain.place_instrument(ground_xy=np.asarray(body.ground_mm) * 1e-3, client=client)


@router.get("/placement", response_model=PlacementView | None)
def placement(session: SessionDep) -> PlacementView | None:
    return session.terrain.placement_view()


@router.post("/placement/insert", response_model=ProgramView)
def insert(session: SessionDep, client: ClientDep) -> ProgramView:
    """Insert the current placement's statements into the program at the selection."""
    return session.terrain.insert_placement(client=client)


@router.post("/placement/goto", response_model=StateOut)
def goto(body: GotoIn, session: SessionDep, client: ClientDep) -> StateOut:
    """Put the virtual arm at a placement candidate's configuration."""
    return StateOut.from_state(session.terrain.goto_placement(body.candidate - 1, client=client))
