"""Fixtures of the console-session tests: the default cell with its collision model (built once
per module: it takes seconds) and a fresh session on it per test, in virtual time (``clock``)."""

from __future__ import annotations

import pytest

from server.console import Session
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel


@pytest.fixture(scope="module")
def cell_and_scene():
    cell = load_cell(DEFAULT_CELL)
    return cell, SceneModel.from_cell(cell)


class ManualClock:
    """Virtual time for the session: it moves only when a test advances it."""

    def __init__(self, t: float = 1000.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t

    def advance(self, seconds: float) -> None:
        self.t += seconds


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock()


@pytest.fixture
def session(cell_and_scene, clock):
    cell, scene = cell_and_scene
    s = Session(cell, scene=scene, clock=clock, wall_clock=clock)
    yield s
    s.close()
