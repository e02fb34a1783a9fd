"""A moved object set down seated in a feature as it stood at load (the peg inserted in HOLE2)
touches its support by design: ``CellCollision`` leaves that resting contact out, as it does at
load, and keeps it in wherever the object is not seated (sunk into the plate, tilted, beside the
hole). The oracle is the collision scene asked directly, which sees the peg touch the plate."""

from __future__ import annotations

import numpy as np
import pytest

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.cells.object_world import seated_feature
from shared.collision import SceneModel
from shared.collision.cell_check import CellCollision
from shared.spatial import rpy_to_matrix


@pytest.fixture(scope="module")
def cell():
    return load_cell(DEFAULT_CELL)


@pytest.fixture(scope="module")
def cc(cell) -> CellCollision:
    return CellCollision(cell, scene=SceneModel.from_cell(cell, leaf_size=8))


def _peg_in(cell, hole: str, shift=(0.0, 0.0, 0.0), turn_deg=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The peg standing in ``hole`` as it stands in HOLE1 at load, shifted (m) and turned."""
    load = np.asarray(cell.object("peg").world_T_object, dtype=float)
    feature_T_peg = np.linalg.inv(cell.features["HOLE1"].world_T_feature) @ load
    pose = cell.features[hole].world_T_feature @ feature_T_peg
    pose[:3, :3] = pose[:3, :3] @ rpy_to_matrix(np.radians(turn_deg))
    pose[:3, 3] += shift
    return pose


def test_a_peg_seated_in_hole2_is_not_a_collision_with_its_plate(cell, cc) -> None:
    poses = {"peg": _peg_in(cell, "HOLE2")}
    assert ("peg", "plate") in {tuple(sorted((p.a, p.b))) for p in cc.scene.check(cell.q_home, object_poses=poses).pairs}  # it touches
    assert seated_feature(cell, "peg", poses["peg"]) == "HOLE2"
    assert not cc.check(cell.q_home, object_poses=poses).colliding
    assert cc.touching(cell.q_home, object_poses=poses)[0] == ()


def test_a_square_peg_turned_about_the_holes_axis_is_still_seated(cell) -> None:
    assert seated_feature(cell, "peg", _peg_in(cell, "HOLE2", turn_deg=(0.0, 0.0, 90.0))) == "HOLE2"


@pytest.mark.parametrize("shift, turn", [((0.0, 0.0, -0.008), (0.0, 0.0, 0.0)),   # sunk 8 mm into the floor
                                         ((0.0, 0.015, -0.005), (0.0, 0.0, 0.0)),  # beside the hole, in the plate
                                         ((0.0, 0.0, 0.0), (12.0, 0.0, 0.0))])     # tilted in the hole
def test_a_peg_not_seated_still_collides_with_the_plate(cell, cc, shift, turn) -> None:
    poses = {"peg": _peg_in(cell, "HOLE2", shift, turn)}
    assert seated_feature(cell, "peg", poses["peg"]) is None
    report = cc.check(cell.q_home, object_poses=poses)
    assert report.colliding and ("peg", "plate") in {tuple(sorted(p)) for p in report.pairs}
