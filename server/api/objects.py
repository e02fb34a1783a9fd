"""The cell's cameras and correcting a virtual object's pose from a camera image (§4.2.3)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter
from pydantic import BaseModel, Field

from server.api.deps import ClientDep, SessionDep
from server.api_models import ApiIn
from server.console import LocatedView

router = APIRouter(prefix="/api", tags=["objects"])


class CameraOut(BaseModel):
    name: str
    K: list[list[float]] = Field(description="intrinsics, pixels")
    world_T_camera: list[list[float]] = Field(description="pose; +z is the optical axis, m")
    width: int
    height: int


class KeypointsOut(BaseModel):
    object: str
    keypoints: list[list[float]] = Field(description="feature points in the object's frame, m, in the order pixels are given")


PIXEL_BOUND = 1e6
"""pixels: |u| and |v| above this are no point of any image."""

Pixel = Annotated[float, Field(ge=-PIXEL_BOUND, le=PIXEL_BOUND)]


class LocateIn(ApiIn):
    camera: str = Field(max_length=200)
    pixels: list[tuple[Pixel, Pixel]] = Field(max_length=1000, description="(u, v) of each feature point in the image, in keypoint order")


@router.get("/cameras", response_model=list[CameraOut])
def cameras(session: SessionDep) -> list[CameraOut]:
    return [CameraOut(name=c.name, K=c.K.tolist(), world_T_camera=c.world_T_camera.tolist(), width=c.width, height=c.height)
            for c in session.cell.cameras.values()]


@router.get("/objects/keypoints", response_model=list[KeypointsOut])
def keypoints(session: SessionDep) -> list[KeypointsOut]:
    """The objects a camera can locate (four or more feature points) and their feature points."""
    return [KeypointsOut(object=o.name, keypoints=o.keypoints.tolist()) for o in session.cell.objects if len(o.keypoints) >= 4]


@router.post("/objects/{name}/locate", response_model=LocatedView)
def locate(name: str, body: LocateIn, session: SessionDep, client: ClientDep) -> LocatedView:
    """Correct the virtual object's pose from its feature points seen at ``pixels`` in the
    named camera's image; 400 when the pixels do not fit (wrong order, wrong object) or cannot
    determine a pose (repeated or collinear points)."""
    return session.locator.locate_object(name, body.camera, body.pixels, client=client)
