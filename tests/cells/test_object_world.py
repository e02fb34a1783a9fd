"""``shared.cells.object_world.ObjectWorld``: a grasp fixes the object to the tool, a release
leaves it where the tool put it, task calls are read case-insensitively, robot reports and
re-syncs are taken, and the divergence names the worst object.

Every expected pose is made here by hand (rotations about one axis, translations) and composed
with numpy; none is computed by the code under test."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.cells.object_world import ObjectWorld

# the peg of peg_in_hole.toml: work frame at (550, 0, 350) mm, the peg at (0, -80, 50) mm in it,
# no rotation
PEG_CELL_POSE = np.array([[1.0, 0, 0, 0.55], [0, 1.0, 0, -0.08], [0, 0, 1.0, 0.40], [0, 0, 0, 1.0]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def trans(x: float, y: float, z: float) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = (x, y, z)
    return t


# the tool, pointing down (flipped about x) just above the peg, turned 30 deg about the vertical
TOOL_AT_PEG = trans(0.55, -0.08, 0.47) @ rot_z(math.radians(30)) @ rot_x(math.pi)
# a rigid motion of the tool: up 10 cm, over 5 cm, turned 40 deg about the world's vertical
MOTION = trans(0.05, 0.02, 0.10) @ rot_z(math.radians(40))


@pytest.fixture(scope="module")
def cell():
    return load_cell(DEFAULT_CELL)


@pytest.fixture
def world(cell) -> ObjectWorld:
    return ObjectWorld(cell)


def test_objects_start_at_their_cell_pose(world: ObjectWorld) -> None:
    np.testing.assert_allclose(world.world_T_object("peg"), PEG_CELL_POSE, atol=1e-12)
    assert world.held is None and world.poses() == {}


def test_a_grasp_fixes_the_object_to_the_tool(world: ObjectWorld) -> None:
    world.grasp("peg", TOOL_AT_PEG)
    assert world.held == "peg"
    # the grasp itself moves nothing
    np.testing.assert_allclose(world.world_T_object("peg", TOOL_AT_PEG), PEG_CELL_POSE, atol=1e-12)
    # moving the tool by MOTION moves the peg by MOTION (a rigid attachment)
    moved_tool = MOTION @ TOOL_AT_PEG
    expected = MOTION @ PEG_CELL_POSE
    np.testing.assert_allclose(world.world_T_object("peg", moved_tool), expected, atol=1e-12)
    np.testing.assert_allclose(world.poses(moved_tool)["peg"], expected, atol=1e-12)
    # the peg keeps its pose relative to the tool: tool^-1 @ peg is the same before and after
    rel_before = np.linalg.inv(TOOL_AT_PEG) @ PEG_CELL_POSE
    rel_after = np.linalg.inv(moved_tool) @ world.world_T_object("peg", moved_tool)
    np.testing.assert_allclose(rel_after, rel_before, atol=1e-12)
    # without a tool pose, the held object is not among the moved ones
    assert "peg" not in world.poses()


def test_a_release_leaves_the_object_where_the_tool_put_it(world: ObjectWorld) -> None:
    world.grasp("peg", TOOL_AT_PEG)
    world.release(MOTION @ TOOL_AT_PEG)
    assert world.held is None and world.tcp_T_held is None
    expected = MOTION @ PEG_CELL_POSE
    # wherever the tool goes next, the peg stays
    elsewhere = trans(0.3, 0.3, 0.9)
    np.testing.assert_allclose(world.world_T_object("peg", elsewhere), expected, atol=1e-12)
    np.testing.assert_allclose(world.poses(elsewhere)["peg"], expected, atol=1e-12)
    # a second grasp takes it from there, not from its cell pose
    world.grasp("peg", elsewhere)
    lifted = trans(0.0, 0.0, 0.05) @ elsewhere
    np.testing.assert_allclose(world.world_T_object("peg", lifted), trans(0.0, 0.0, 0.05) @ expected, atol=1e-12)


def test_release_with_nothing_held_changes_nothing(world: ObjectWorld) -> None:
    world.release(TOOL_AT_PEG)
    assert world.held is None and world.placed == {}


def test_apply_task_reads_grasp_release_insert_case_insensitively(world: ObjectWorld) -> None:
    assert world.resolve("PeG") == "peg" and world.resolve("bolt") is None
    assert world.apply_task("GRASP", ("PEG",), TOOL_AT_PEG)
    assert world.held == "peg"  # the cell's spelling
    lifted = MOTION @ TOOL_AT_PEG
    assert world.apply_task("Release_Gently", (), lifted)
    assert world.held is None
    np.testing.assert_allclose(world.world_T_object("peg"), MOTION @ PEG_CELL_POSE, atol=1e-12)
    # grasp* is a prefix: grasp_peg counts; insert* lets go like release*
    assert world.apply_task("grasp_peg", ("Peg",), lifted)
    assert world.held == "peg"
    down = trans(0.0, 0.0, -0.02) @ lifted
    assert world.apply_task("INSERT_PEG", ("PEG", "HOLE2"), down)
    # an insertion seats the peg in the hole it names, as it stood in HOLE1 at load, still held
    assert world.held == "peg"
    hole1, hole2 = (world.cell.features[h].world_T_feature for h in ("HOLE1", "HOLE2"))
    seated = hole2 @ np.linalg.inv(hole1) @ PEG_CELL_POSE
    np.testing.assert_allclose(world.world_T_object("peg", down), seated, atol=1e-12)
    assert world.apply_task("release", (), down)
    np.testing.assert_allclose(world.world_T_object("peg"), seated, atol=1e-12)
    # with no hole named it lets go where the tool is
    world.apply_task("grasp", ("peg",), down)
    assert world.apply_task("insert", ("peg",), MOTION @ down)
    assert world.held is None
    np.testing.assert_allclose(world.world_T_object("peg"), MOTION @ seated, atol=1e-12)


def test_apply_task_ignores_unknown_objects_and_tasks(world: ObjectWorld) -> None:
    assert not world.apply_task("grasp", ("bolt",), TOOL_AT_PEG)
    assert not world.apply_task("grasp", (), TOOL_AT_PEG)  # nothing named
    assert not world.apply_task("release", (), TOOL_AT_PEG)  # nothing held
    assert not world.apply_task("insert_peg", ("peg", "HOLE2"), TOOL_AT_PEG)
    assert not world.apply_task("wave", ("peg",), TOOL_AT_PEG)
    assert world.held is None and world.placed == {}
    world.apply_task("grasp", ("peg",), TOOL_AT_PEG)
    assert not world.apply_task("grasp", ("bolt",), MOTION @ TOOL_AT_PEG)
    assert world.held == "peg"  # an unknown grasp does not drop what is held


def test_take_reported_ignores_unknown_names_and_the_held_object_rides_with_the_tool(world: ObjectWorld) -> None:
    peg_at = trans(0.6, 0.1, 0.42) @ rot_z(0.3)
    plate_at = trans(0.55, 0.0, 0.37)
    robot_tool = peg_at @ trans(0.0, 0.0, 0.07) @ rot_x(math.pi)
    world.take_reported({"peg": peg_at, "plate": plate_at, "bolt": trans(1, 1, 1)}, "peg", robot_tool)
    assert world.held == "peg"
    assert set(world.placed) == {"plate"} and "bolt" not in world.poses(robot_tool)
    np.testing.assert_allclose(world.world_T_object("plate"), plate_at, atol=1e-12)
    np.testing.assert_allclose(world.world_T_object("peg", robot_tool), peg_at, atol=1e-12)
    np.testing.assert_allclose(world.world_T_object("peg", MOTION @ robot_tool), MOTION @ peg_at, atol=1e-12)
    # a report holding nothing: the peg lies where reported
    world.take_reported({"peg": peg_at}, None, MOTION @ robot_tool)
    assert world.held is None
    np.testing.assert_allclose(world.world_T_object("peg", MOTION @ robot_tool), peg_at, atol=1e-12)
    # a held name the report does not place (or the cell lacks) is not held
    world.take_reported({"plate": plate_at}, "bolt", robot_tool)
    assert world.held is None and world.tcp_T_held is None


def test_take_reported_copies_the_poses(world: ObjectWorld) -> None:
    peg_at = trans(0.6, 0.1, 0.42)
    world.take_reported({"peg": peg_at}, None, TOOL_AT_PEG)
    peg_at[0, 3] = 9.0
    assert world.world_T_object("peg")[0, 3] == pytest.approx(0.6)


def test_take_resyncs_and_what_this_side_held_stays_where_its_tool_holds_it(cell) -> None:
    virtual, remote = ObjectWorld(cell), ObjectWorld(cell)
    virtual.grasp("peg", TOOL_AT_PEG)
    virtual_tool_now = MOTION @ TOOL_AT_PEG  # the virtual arm carried the peg off
    plate_at = trans(0.55, 0.01, 0.37)
    remote.place("plate", plate_at)  # the robot holds nothing and saw the plate moved
    virtual.take(remote, virtual_tool_now)
    assert virtual.held is None and virtual.tcp_T_held is None
    np.testing.assert_allclose(virtual.world_T_object("peg"), MOTION @ PEG_CELL_POSE, atol=1e-12)
    np.testing.assert_allclose(virtual.world_T_object("plate"), plate_at, atol=1e-12)
    # the copy is the virtual side's own
    remote.placed["plate"][0, 3] = 5.0
    assert virtual.world_T_object("plate")[0, 3] == pytest.approx(0.55)


def test_take_adopts_the_other_sides_grip(cell) -> None:
    virtual, remote = ObjectWorld(cell), ObjectWorld(cell)
    virtual.place("peg", trans(0.4, 0.0, 0.36))
    remote_tool = trans(0.55, -0.08, 0.47) @ rot_x(math.pi)
    remote.grasp("peg", remote_tool)  # the robot holds the peg at its cell pose
    virtual.take(remote, TOOL_AT_PEG)
    assert virtual.held == "peg" and "peg" not in virtual.placed
    # the virtual arm's tool now carries the peg with the robot's grip
    expected = MOTION @ PEG_CELL_POSE
    np.testing.assert_allclose(virtual.world_T_object("peg", MOTION @ remote_tool), expected, atol=1e-12)
    remote.tcp_T_held[0, 3] = 7.0  # the grip was copied
    assert virtual.tcp_T_held[0, 3] != pytest.approx(7.0)


def test_divergence_none_when_both_sides_agree(cell) -> None:
    remote, expected = ObjectWorld(cell), ObjectWorld(cell)
    assert remote.divergence(expected) == (None, 0.0)
    remote.place("peg", PEG_CELL_POSE)  # reported exactly where the model has it
    assert remote.divergence(expected) == (None, 0.0)
    remote.grasp("peg", TOOL_AT_PEG)
    expected.grasp("peg", TOOL_AT_PEG)
    assert remote.divergence(expected) == (None, 0.0)


def test_divergence_infinite_when_the_held_object_differs(cell) -> None:
    remote, expected = ObjectWorld(cell), ObjectWorld(cell)
    remote.grasp("peg", TOOL_AT_PEG)
    assert remote.divergence(expected) == ("peg", math.inf)
    assert expected.divergence(remote) == ("peg", math.inf)
    expected.grasp("plate", TOOL_AT_PEG)
    name, d = remote.divergence(expected)
    assert name == "peg" and d == math.inf


def test_divergence_is_the_distance_of_the_worst_object(cell) -> None:
    remote, expected = ObjectWorld(cell), ObjectWorld(cell)
    remote.place("peg", trans(0.003, 0.004, 0.0) @ PEG_CELL_POSE)  # 3-4-5: 5 mm off
    name, d = remote.divergence(expected)
    assert name == "peg" and d == pytest.approx(0.005, abs=1e-12)
    # a rotation alone does not count: the distance is between the origins
    remote.place("peg", PEG_CELL_POSE @ rot_z(1.0))
    assert remote.divergence(expected) == (None, 0.0)
    plate = cell.object("plate").world_T_object
    remote.place("plate", trans(0.0, 0.0, 0.012) @ plate)
    remote.place("peg", trans(0.0, 0.002, 0.0) @ PEG_CELL_POSE)
    name, d = remote.divergence(expected)
    assert name == "plate" and d == pytest.approx(0.012, abs=1e-12)
    # measured against where the expected side moved it
    expected.place("plate", trans(0.0, 0.0, 0.011) @ plate)
    name, d = remote.divergence(expected)
    assert name == "peg" and d == pytest.approx(0.002, abs=1e-12)
