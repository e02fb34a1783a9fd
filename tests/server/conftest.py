"""Fixtures of the console-session tests: the default cell with its collision model (built once
per module: it takes seconds) and a fresh session on it per test."""

from __future__ import annotations

import pytest

from server.session import Session
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel


@pytest.fixture(scope="module")
def cell_and_scene():
    cell = load_cell(DEFAULT_CELL)
    return cell, SceneModel.from_cell(cell)


@pytest.fixture
def session(cell_and_scene):
    cell, scene = cell_and_scene
    s = Session(cell, scene=scene)
    yield s
    s.close()
