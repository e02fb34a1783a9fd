"""The rover cells' ground in the physics world: the height field of robot_sim.physics.terrain."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from robot_sim.physics.terrain import HeightGrid, cell_height_grid, height_grid, rasterise, terrain_geoms
from shared.cells.loader import load_cell
from shared.terrain.cell import TERRAIN_OBJECT, cell_terrain_mesh, load_cell_terrain

ROOT = Path(__file__).resolve().parents[2]
CELL = ROOT / "assets" / "cells" / "rover_terrain.toml"


@pytest.fixture(scope="module")
def cell():
    return load_cell(str(CELL))


@pytest.fixture(scope="module")
def ground_model(cell):
    """The terrain alone as MuJoCo compiles it."""
    obj = next(o for o in cell.objects if o.name == TERRAIN_OBJECT)
    assets, geoms = terrain_geoms(cell, obj, friction=0.3, contype=1)
    xml = f"<mujoco><asset>{''.join(assets)}</asset><worldbody>{''.join(geoms)}</worldbody></mujoco>"
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


@pytest.fixture(scope="module")
def world(cell):
    from robot_sim.settings import WorldSettings
    from robot_sim.worlds import make_world

    return make_world(cell, WorldSettings())


def _ray_heights(model, data, xy: np.ndarray) -> np.ndarray:
    geomid = np.zeros(1, dtype=np.int32)
    out = []
    for x, y in xy:
        d = mujoco.mj_ray(model, data, np.array([x, y, 1.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid)
        out.append(1.0 - d if d >= 0 else np.nan)
    return np.array(out)


def test_height_field_matches_the_mesh(cell, ground_model):
    model, data = ground_model
    grid = cell_height_grid(cell)
    mesh = cell_terrain_mesh(cell)
    assert grid.h <= 2e-3  # 1-2 mm cells on the 20k-triangle lunar terrain
    rng = np.random.default_rng(1)
    (cx, cy), (rx, ry) = grid.centre, grid.radius
    xy = np.c_[rng.uniform(cx - 0.95 * rx, cx + 0.95 * rx, 300), rng.uniform(cy - 0.95 * ry, cy + 0.95 * ry, 300)]
    z_ray = _ray_heights(model, data, xy)
    z_mesh = np.array([rasterise(mesh.vertices, mesh.faces, x, y, 1.0, 1, 1)[0, 0] for x, y in xy])
    inside = np.isfinite(z_mesh)
    assert inside.sum() > 250
    err = np.abs(z_ray - z_mesh)[inside]
    # MuJoCo's surface is the mesh sampled on the grid: off by a fraction of a cell's slope change
    assert np.median(err) < 0.05e-3
    assert err.max() < grid.h
    # and it is the grid as this module reads it (MuJoCo's row order and cell split)
    assert np.allclose(z_ray, grid.height_at(xy[:, 0], xy[:, 1]), atol=1e-6)


def test_grid_of_a_tilted_plane_is_exact():
    # two triangles of the plane z = 0.1 x - 0.05 y + 0.2 over [0, 1] x [0, 1]
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    v[:, 2] = 0.1 * v[:, 0] - 0.05 * v[:, 1] + 0.2
    f = np.array([[0, 1, 2], [0, 2, 3]])
    g = height_grid(v, f)
    assert isinstance(g, HeightGrid) and not np.isnan(g.heights).any()
    x, y = np.random.default_rng(0).uniform(0, 1, (2, 100))
    assert np.allclose(g.height_at(x, y), 0.1 * x - 0.05 * y + 0.2, atol=1e-9)


def _terrain_contact(world, q) -> bool:
    model = world.model
    data = mujoco.MjData(model)
    terrain = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "terrain/hfield")
    data.qpos[world._qadr] = q
    mujoco.mj_forward(model, data)
    arm = np.asarray(model.geom_contype) == 2
    return any(terrain in (c.geom1, c.geom2) and arm[c.geom1 if c.geom2 == terrain else c.geom2] and c.dist <= 0
               for c in data.contact[: data.ncon])


def test_instrument_above_and_into_the_ground(cell, world):
    checker = load_cell_terrain(cell).checker
    above = np.radians([-27.0, -30.0, -210.0])  # the program's placement pose, about 17 mm up
    into = np.radians([-27.0, -40.0, -210.0])  # lowered well past the ground
    assert checker.min_distance(above) > 0.01 and checker.min_distance(into) <= 0.0
    assert not _terrain_contact(world, above)
    assert _terrain_contact(world, into)


def test_world_builds_and_the_ground_holds_the_instrument(world, cell):
    model = world.model
    g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "terrain/hfield")
    assert g >= 0 and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_HFIELD
    assert (model.geom_contype[g], model.geom_conaffinity[g], model.geom_group[g]) == (1, 0, 0)
    assert model.nhfield == 1 and model.hfield_nrow[0] * model.hfield_ncol[0] <= 500 * 500
    q0 = np.array(cell.q_home, dtype=float)
    for _ in range(20):  # resting at home
        world.servo(q0)
    assert np.all(np.isfinite(world.data.qpos))
    # unstow over the target, then drive the shoulder down past the ground: the ground stops it
    over, down = np.radians([-27.0, -30.0, -210.0]), np.radians([-27.0, -40.0, -210.0])
    for k in range(1, 51):
        world.servo(q0 + (over - q0) * k / 50)
    for k in range(1, 51):
        world.servo(over + (down - over) * k / 50)
    q = world.data.qpos[world._qadr]
    assert np.all(np.isfinite(world.data.qpos))
    assert np.degrees(q[1]) > -38.0  # held up by the ground, short of the target
    assert world.contact(noise=False).what == TERRAIN_OBJECT
