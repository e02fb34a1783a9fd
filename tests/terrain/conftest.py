"""Small terrains shared by the terrain tests (built once per session)."""

from __future__ import annotations

import numpy as np
import pytest

from shared.cells.loader import load_cell
from shared.paths import ASSETS_DIR
from shared.terrain.arm import arm_model
from shared.terrain.cell import load_cell_terrain
from shared.terrain.checks import TerrainChecker
from shared.terrain.filter import grid_density_filter
from shared.terrain.generator import generate_points, make_spec
from shared.terrain.tree import build_tree
from shared.terrain.triangulate import triangulate_25d

CELL = ASSETS_DIR / "cells" / "rover_terrain.toml"


@pytest.fixture(scope="session")
def small_spec():
    return make_spec(seed=11, origin=(0.2, -0.8), size=(1.2, 1.2))


@pytest.fixture(scope="session")
def small_mesh(small_spec):
    points = generate_points(small_spec, 6000)
    return triangulate_25d(points[grid_density_filter(points)])


@pytest.fixture(scope="session")
def small_tree(small_mesh):
    return build_tree(small_mesh, branching=8, leaf_size=4)


@pytest.fixture(scope="session")
def cell():
    return load_cell(CELL)


@pytest.fixture(scope="session")
def cell_terrain(cell):
    return load_cell_terrain(cell)


@pytest.fixture(scope="session")
def small_checker(small_tree, cell):
    return TerrainChecker(small_tree, arm_model(cell.robot), cell.world_T_base)


@pytest.fixture(scope="session")
def random_q(cell):
    rng = np.random.default_rng(7)
    return rng.uniform(cell.robot.lower, cell.robot.upper, (60, cell.robot.dof))
