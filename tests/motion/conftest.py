"""Fixtures for the planner tests: the peg-in-hole cell and a wall sensor model."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from shared.cells.cell import Cell
from shared.cells.loader import load_cell
from shared.motion import CellFrames
from shared.paths import ASSETS_DIR
from shared.robots.model import Robot


@dataclass
class Wall:
    """A horizontal wall at world height ``height``: the tool centre point below it is in contact
    and feels a spring force ``stiffness * depth``. Counts its calls (to see it is consulted)."""

    robot: Robot
    frames: CellFrames
    height: float
    stiffness: float = 1000.0
    calls: int = 0

    def depth(self, q: np.ndarray) -> float:
        return self.height - float(self.frames.world_T_tcp(self.robot, q)[2, 3])

    def force(self, t: float, q: np.ndarray) -> float:
        self.calls += 1
        return self.stiffness * max(0.0, self.depth(q))

    def contact(self, t: float, q: np.ndarray) -> bool:
        self.calls += 1
        return self.depth(q) >= 0.0


@pytest.fixture(scope="session")
def cell() -> Cell:
    return load_cell(ASSETS_DIR / "cells" / "peg_in_hole.toml")


@pytest.fixture(scope="session")
def frames(cell: Cell) -> CellFrames:
    return CellFrames.from_cell(cell)


@pytest.fixture
def make_wall(cell: Cell, frames: CellFrames):
    def make(height: float, stiffness: float = 1000.0) -> Wall:
        return Wall(cell.robot, frames, height, stiffness)

    return make
