"""Fixtures for the collision tests: the peg-in-hole cell, its collision model, coal on it."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))


@pytest.fixture(scope="session")
def cell():
    from shared.cells.loader import DEFAULT_CELL, load_cell

    return load_cell(DEFAULT_CELL)


@pytest.fixture(scope="session")
def model(cell):
    from shared.collision import SceneModel

    m = SceneModel.from_cell(cell)
    m.check(cell.q_home)  # compile (or load the numba cache) once
    return m


@pytest.fixture(scope="session")
def coal_scene(model):
    from coal_reference import CoalScene

    return CoalScene(model)
