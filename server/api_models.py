"""Typed request and response bodies of the console's HTTP API (units in the field names)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, Field

from server.session import VirtualState
from shared.spatial import matrix_to_rpy


class HealthOut(BaseModel):
    status: Literal["ok"]
    cell: str
    robot: str


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


class SetJointsIn(BaseModel):
    deg: list[float] = Field(description="full joint vector, degrees")


class JogJointIn(BaseModel):
    joint: int = Field(ge=1, description="joint number, 1-based")
    delta_deg: float = Field(description="rotation about the joint's own z axis, degrees")


class JogToolIn(BaseModel):
    frame: Literal["world", "base", "work", "tool"] = "world"
    constraint: Literal["x", "y", "z", "xy", "yz", "xz"] = "x"
    motion: Literal["translate", "rotate"] = "translate"
    displacement: tuple[float, float, float] = Field(description="mm for translate, deg (rotation vector) for rotate")
