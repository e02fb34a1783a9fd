"""The fixed frames a motion statement may refer to, taken once from the cell.

``world_T_base`` places the robot, ``world_T_work`` is the cell's work frame, and
``tool_T_tcp`` is the tool centre point (the gripper's centre in the peg cell) relative to the
robot's kinematic tool frame. Cartesian statements move the tool centre point; TOOL-frame
targets are relative to its pose at the start of the statement.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.cells.cell import Cell
from shared.language.statements import Frame
from shared.robots.model import Robot
from shared.spatial import invert


@dataclass(frozen=True)
class CellFrames:
    world_T_base: np.ndarray
    world_T_work: np.ndarray
    tool_T_tcp: np.ndarray

    @classmethod
    def identity(cls) -> "CellFrames":
        """No cell: world, base and work coincide and the tool centre point is the tool frame."""
        return cls(np.eye(4), np.eye(4), np.eye(4))

    @classmethod
    def from_cell(cls, cell: Cell) -> "CellFrames":
        return cls(cell.world_T_base, cell.frame("work"), cell.flange_T_tcp)

    def world_T_tcp(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        return self.world_T_base @ robot.fk(q) @ self.tool_T_tcp

    def base_T_tool(self, world_T_tcp: np.ndarray) -> np.ndarray:
        """The robot's kinematic tool pose that puts the tool centre point at ``world_T_tcp``."""
        return invert(self.world_T_base) @ world_T_tcp @ invert(self.tool_T_tcp)

    def world_T_frame(self, frame: Frame, world_T_tcp_start: np.ndarray) -> np.ndarray:
        """Where a statement's target frame is; TOOL is the tool centre point at the statement's start."""
        if frame is Frame.WORLD:
            return np.eye(4)
        if frame is Frame.BASE:
            return self.world_T_base
        if frame is Frame.WORK:
            return self.world_T_work
        return world_T_tcp_start
