"""Typed request and response bodies of the console's HTTP API (units in the field names)."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from server.console import VirtualState
from server.loop_watch import LoopLag
from shared.spatial import matrix_to_rpy

MAX_COUNT = 1_000_000
"""Largest index, count or number a request may carry (a program never holds this many)."""
MAX_ANGLE_DEG = 3600.0
"""deg: largest joint angle or rotation a request may carry (ten turns)."""
MAX_LENGTH_MM = 1e6
"""mm: largest length or coordinate a request may carry (a kilometre)."""
MAX_TIME_S = 1e6
"""s: largest time a request may carry."""


class ApiIn(BaseModel):
    """Base of every request body: numbers are finite (a ``"NaN"`` string, which pydantic would
    turn into a float, is refused too)."""

    model_config = ConfigDict(allow_inf_nan=False)


Degrees = Annotated[float, Field(ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG)]
Millimetres = Annotated[float, Field(ge=-MAX_LENGTH_MM, le=MAX_LENGTH_MM)]


class HealthOut(BaseModel):
    status: Literal["ok"]
    cell: str
    robot: str
    loop: LoopLag | None = Field(None, description="the web server's event-loop lag (with ?loop=true; ?loop=reset starts a new window)")


class StateOut(BaseModel):
    q_deg: list[float] = Field(description="virtual robot joint angles, degrees")
    tool_xyz_mm: list[float] = Field(description="tool point position in the world frame, mm")
    tool_rpy_deg: list[float] = Field(description="tool orientation in the world frame, fixed-axis XYZ, degrees")
    blocked: str | None = Field(None, description="why the last jog stopped, if it did")
    message: str = ""
    version: int

    @classmethod
    def from_state(cls, state: VirtualState) -> "StateOut":
        jog = state.last_jog
        return cls(
            q_deg=np.degrees(state.q).tolist(),
            tool_xyz_mm=(state.world_T_tcp[:3, 3] * 1e3).tolist(),
            tool_rpy_deg=np.degrees(matrix_to_rpy(state.world_T_tcp[:3, :3])).tolist(),
            blocked=jog.blocked if jog else None,
            message=jog.message if jog else "",
            version=state.version,
        )


class SetJointsIn(ApiIn):
    deg: list[Degrees] = Field(max_length=64, description="full joint vector, degrees")


class JogJointIn(ApiIn):
    joint: int = Field(ge=1, le=64, description="joint number, 1-based")
    delta_deg: Degrees = Field(description="rotation about the joint's own z axis, degrees")


class JogToolIn(ApiIn):
    frame: Literal["world", "base", "work", "tool"] = "world"
    constraint: Literal["x", "y", "z", "xy", "yz", "xz"] = "x"
    motion: Literal["translate", "rotate"] = "translate"
    displacement: tuple[Millimetres, Millimetres, Millimetres] = Field(description="mm for translate, deg (rotation vector) for rotate")
