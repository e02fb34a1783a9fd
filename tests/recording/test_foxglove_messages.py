"""The recording's 3D messages are what Foxglove reads and draw the console's scene.

Every message validates against the published schemas (assets/foxglove_schemas/) for every
shipped cell and for a UR5 cell (mesh links from a URDF, every primitive kind among its objects);
the transforms chain to the robot model's forward kinematics and to the tool centre point; the
scene's entities hang on frames the transforms provide, in the page's colours.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from foxglove_validate import FoxgloveSchemaError, validate
from server.recording import foxglove as fg
from shared.cells.loader import load_cell
from shared.errors import InputError, UnknownNameError
from shared.motion.frames import CellFrames
from shared.paths import ASSETS_DIR
from shared.robots.shapes import shape_mesh
from webui.ghost import GHOST_COLOR, GHOST_OPACITY

T_NS = 1_764_000_000_123_456_789
SHIPPED = sorted(p.name for p in (ASSETS_DIR / "cells").glob("*.toml"))

UR5_CELL = f"""
name = "ur5_shapes"
[units]
length = "mm"
angle = "deg"
[robot]
ref = "{ASSETS_DIR / 'robots' / 'ur5' / 'ur5_robot.urdf'}"
xyz = [100.0, -50.0, 400.0]
rpy = [0.0, 0.0, 30.0]
q_home = [10.0, -60.0, 80.0, -110.0, -90.0, 0.0]
tcp = {{ xyz = [0.0, 0.0, 120.0] }}
[[objects]]
name = "kit"
xyz = [500.0, 0.0, 0.0]
rpy = [0.0, 90.0, 0.0]
color = [10, 20, 30]
shapes = [
  {{ shape = "box", size = [100.0, 200.0, 30.0] }},
  {{ shape = "sphere", radius = 40.0, xyz = [0.0, 0.0, 100.0] }},
  {{ shape = "cylinder", radius = 20.0, length = 90.0, xyz = [0.0, 100.0, 0.0] }},
  {{ shape = "capsule", radius = 15.0, length = 120.0, xyz = [0.0, -100.0, 0.0], rpy = [90.0, 0.0, 0.0] }},
]
"""


@pytest.fixture(scope="module")
def cells(tmp_path_factory: pytest.TempPathFactory) -> dict:
    ur5 = tmp_path_factory.mktemp("cells") / "ur5_shapes.toml"
    ur5.write_text(UR5_CELL, encoding="utf-8")
    out = {name: load_cell(ASSETS_DIR / "cells" / name) for name in SHIPPED}
    out["ur5_shapes.toml"] = load_cell(ur5)
    return out


CELLS = [*SHIPPED, "ur5_shapes.toml"]


def random_qs(robot, count: int, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lower, upper = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    return rng.uniform(lower, upper, size=(count, robot.dof))


def transform_matrix(t: dict) -> np.ndarray:
    out = np.eye(4)
    r = t["rotation"]
    out[:3, :3] = Rotation.from_quat([r["x"], r["y"], r["z"], r["w"]]).as_matrix()
    out[:3, 3] = [t["translation"][k] for k in "xyz"]
    return out


def pose_matrix(pose: dict) -> np.ndarray:
    return transform_matrix({"rotation": pose["orientation"], "translation": pose["position"]})


def world_poses(message: dict) -> dict[str, np.ndarray]:
    """Chain a FrameTransforms from ``world``: every child frame's pose in the world."""
    known = {"world": np.eye(4)}
    for t in message["transforms"]:  # parents come first
        known[t["child_frame_id"]] = known[t["parent_frame_id"]] @ transform_matrix(t)
    return known


# -- schemas ------------------------------------------------------------------------------------
def test_schema_bytes_are_the_shipped_files_of_the_four_schemas() -> None:
    assert fg.FOXGLOVE_SCHEMAS == ("foxglove.FrameTransforms", "foxglove.SceneUpdate", "foxglove.PosesInFrame", "foxglove.Log")
    for name in fg.FOXGLOVE_SCHEMAS:
        data = fg.schema_bytes(name)
        assert data == (ASSETS_DIR / "foxglove_schemas" / f"{name}.json").read_bytes()
        assert json.loads(data)["title"] == name
    with pytest.raises(UnknownNameError, match="foxglove.Log"):
        fg.schema_bytes("foxglove.Pose")
    with pytest.raises(InputError, match="foxglove.Log.json"):
        fg.schema_bytes("foxglove.Log", folder=Path("/nonexistent"))


# -- every message validates ----------------------------------------------------------------------
@pytest.mark.parametrize("cell_name", CELLS)
def test_every_message_validates_for_every_cell(cells, cell_name: str) -> None:
    cell = cells[cell_name]
    robot = cell.robot
    for prefix in ("virtual", "remote"):
        for q in [cell.q_home, *random_qs(robot, 3)]:
            message = fg.frame_transforms(robot, q, cell.world_T_base, prefix, T_NS, tool_T_tcp=cell.flange_T_tcp)
            validate("foxglove.FrameTransforms", message)
    scene = fg.scene_update(cell, {}, T_NS)
    validate("foxglove.SceneUpdate", scene)
    assert len(json.dumps(scene)) < 1_000_000, "the scene (sent once at the start) stays under a megabyte"
    if cell.objects:
        moved = {cell.objects[0].name: cell.objects[0].world_T_object @ _turn_z(0.3, [0.01, 0.02, 0.03])}
        validate("foxglove.SceneUpdate", fg.object_entities(cell, moved, T_NS))
    frames = CellFrames.from_cell(cell)
    path = np.array([frames.world_T_tcp(robot, q)[:3, 3] for q in random_qs(robot, 5)])
    validate("foxglove.PosesInFrame", fg.poses_in_frame(path, T_NS))
    validate("foxglove.PosesInFrame", fg.poses_in_frame(np.zeros((0, 3)), T_NS))
    for level in ("debug", "info", "warning", "error"):
        validate("foxglove.Log", fg.log_message(T_NS, level, "DRAW TO (0, -80, 160) mm IN WORK", "console"))


def _turn_z(angle: float, xyz) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = Rotation.from_euler("z", angle).as_matrix()
    out[:3, 3] = xyz
    return out


# -- transforms are the forward kinematics ------------------------------------------------------
@pytest.mark.parametrize("cell_name", CELLS)
def test_link_transforms_chain_to_the_robot_model_links_and_tool_point(cells, cell_name: str) -> None:
    cell = cells[cell_name]
    robot = cell.robot
    frames = CellFrames.from_cell(cell)
    for q in [cell.q_home, *random_qs(robot, 6, seed=11)]:
        message = fg.frame_transforms(robot, q, cell.world_T_base, "virtual", T_NS, tool_T_tcp=cell.flange_T_tcp)
        assert [t["parent_frame_id"] for t in message["transforms"]][:2] == ["world", "virtual/base"]
        chained = world_poses(message)
        expected = cell.world_T_base @ robot.link_poses(q)
        assert set(chained) == {"world", "virtual/tool", *(fg.link_frame("virtual", i) for i in range(robot.dof + 1))}
        for i in range(robot.dof + 1):
            np.testing.assert_allclose(chained[fg.link_frame("virtual", i)], expected[i], atol=1e-9)
        np.testing.assert_allclose(chained["virtual/tool"], frames.world_T_tcp(robot, q), atol=1e-9)
        assert all(t["timestamp"] == {"sec": 1_764_000_000, "nsec": 123_456_789} for t in message["transforms"])


def test_quaternions_are_unit_and_rebuild_their_matrices_also_at_half_turns() -> None:
    rotations = np.concatenate([
        Rotation.random(500, random_state=3).as_matrix(),
        np.stack([np.diag(d) for d in ([1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0], [1.0, 1.0, 1.0])]),
        Rotation.from_rotvec([[np.pi - 1e-9, 0.0, 0.0], [0.0, 0.0, -np.pi], [1e-12, 0.0, 0.0]]).as_matrix(),
    ])
    q = fg.quaternions_xyzw(rotations)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    assert np.all(q[:, 3] >= 0.0)
    np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(), rotations, atol=1e-12)


# -- the scene ----------------------------------------------------------------------------------
@pytest.mark.parametrize("cell_name", CELLS)
def test_scene_entities_hang_on_frames_the_transforms_provide_in_the_page_colours(cells, cell_name: str) -> None:
    cell = cells[cell_name]
    robot = cell.robot
    provided = {"world"}
    for prefix in ("virtual", "remote"):
        message = fg.frame_transforms(robot, cell.q_home, cell.world_T_base, prefix, T_NS)
        provided |= {t["child_frame_id"] for t in message["transforms"]}
    scene = fg.scene_update(cell, {}, T_NS)
    by_id = {e["id"]: e for e in scene["entities"]}
    assert len(by_id) == len(scene["entities"]), "entity ids are unique"
    assert {e["frame_id"] for e in scene["entities"]} <= provided
    for obj in cell.objects:
        entity = by_id[fg.object_entity_id(obj.name)]
        assert entity["frame_id"] == "world" and not entity["frame_locked"]
    ghost = {"r": GHOST_COLOR[0] / 255, "g": GHOST_COLOR[1] / 255, "b": GHOST_COLOR[2] / 255, "a": GHOST_OPACITY}
    for link, shapes in robot.shapes.items():
        if not shapes:
            continue
        for prefix in ("virtual", "remote"):
            entity = by_id[fg.arm_entity_id(prefix, link)]
            assert entity["frame_id"] == fg.link_frame(prefix, link) and entity["frame_locked"]
            colours = [p["color"] for kind in ("cubes", "spheres", "cylinders", "triangles") for p in entity[kind]]
            assert colours
            if prefix == "remote":
                assert all(c == pytest.approx(ghost) for c in colours)
            else:
                r, g, b = shapes[0].color
                assert all(c == pytest.approx({"r": r / 255, "g": g / 255, "b": b / 255, "a": 1.0}) for c in colours)


def test_objects_are_drawn_where_they_are_and_alone_when_asked(cells) -> None:
    cell = cells["peg_in_hole.toml"]
    peg = cell.object("peg")
    moved = _turn_z(0.5, [0.4, -0.1, 0.2])
    update = fg.object_entities(cell, {"peg": moved}, T_NS, names=["peg"])
    assert [e["id"] for e in update["entities"]] == ["object/peg"]
    (cube,) = update["entities"][0]["cubes"]
    np.testing.assert_allclose(pose_matrix(cube["pose"]), moved @ peg.shapes[0].link_T_shape, atol=1e-12)
    assert [cube["size"][k] for k in "xyz"] == pytest.approx(list(peg.shapes[0].size))
    everything = fg.object_entities(cell, {"peg": moved}, T_NS)
    assert [e["id"] for e in everything["entities"]] == [f"object/{name}" for name in cell.object_names]
    table = next(e for e in everything["entities"] if e["id"] == "object/table")
    np.testing.assert_allclose(pose_matrix(table["cubes"][0]["pose"]),
                               cell.object("table").world_T_object @ cell.object("table").shapes[0].link_T_shape, atol=1e-12)
    with pytest.raises(UnknownNameError, match="peg"):
        fg.object_entities(cell, {"pig": moved}, T_NS)
    with pytest.raises(InputError, match="peg"):
        fg.object_entities(cell, {"peg": np.eye(3)}, T_NS)


def test_primitive_kinds_follow_the_shapes_capsule_as_cylinder_and_two_end_spheres(cells) -> None:
    cell = cells["ur5_shapes.toml"]
    kit = cell.object("kit")
    (entity,) = fg.object_entities(cell, {}, T_NS)["entities"]
    assert (len(entity["cubes"]), len(entity["spheres"]), len(entity["cylinders"]), len(entity["triangles"])) == (1, 3, 2, 0)
    capsule = kit.shapes[3]
    at = kit.world_T_object @ capsule.link_T_shape
    ends = {tuple(np.round(at[:3, 3] + s * at[:3, 2] * capsule.length / 2, 9)) for s in (-1.0, 1.0)}
    centres = {tuple(np.round([s["pose"]["position"][k] for k in "xyz"], 9)) for s in entity["spheres"][1:]}
    assert centres == ends
    assert [entity["spheres"][1]["size"][k] for k in "xyz"] == pytest.approx([2 * capsule.radius] * 3)
    cylinder = entity["cylinders"][1]
    assert [cylinder["size"][k] for k in "xyz"] == pytest.approx([2 * capsule.radius, 2 * capsule.radius, capsule.length])
    # the UR5's links are meshes: triangle lists with indices into their own points
    link = next(e for e in fg.scene_update(cell, {}, T_NS, prefixes=("virtual",))["entities"] if e["id"] == "virtual/link2")
    (triangles,) = link["triangles"]
    mesh = shape_mesh(cell.robot.shapes[2][0])
    assert len(triangles["indices"]) == 3 * len(mesh.faces)
    points = np.array([[p[k] for k in "xyz"] for p in triangles["points"]])
    np.testing.assert_allclose(points[triangles["indices"]], mesh.vertices[mesh.faces.reshape(-1)], atol=1e-6)


def test_a_large_mesh_is_thinned_to_the_budget_and_keeps_its_extent(cells) -> None:
    cell = cells["rover_terrain.toml"]
    terrain = cell.object("terrain")
    original = shape_mesh(terrain.shapes[0])
    assert len(original.faces) > fg.MAX_MESH_TRIANGLES
    (entity,) = fg.object_entities(cell, {}, T_NS, names=["terrain"])["entities"]
    (triangles,) = entity["triangles"]
    indices = np.array(triangles["indices"])
    points = np.array([[p[k] for k in "xyz"] for p in triangles["points"]])
    assert len(indices) % 3 == 0 and fg.MAX_MESH_TRIANGLES // 2 < len(indices) // 3 <= fg.MAX_MESH_TRIANGLES
    assert indices.min() == 0 and indices.max() == len(points) - 1
    size = original.vertices.max(axis=0) - original.vertices.min(axis=0)
    cell_size = float(np.max(size)) / np.sqrt(fg.MAX_MESH_TRIANGLES) * 4
    np.testing.assert_allclose(points.min(axis=0), original.vertices.min(axis=0), atol=cell_size)
    np.testing.assert_allclose(points.max(axis=0), original.vertices.max(axis=0), atol=cell_size)
    faces = indices.reshape(-1, 3)
    assert np.all((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2]))


# -- path, log, times -----------------------------------------------------------------------------
def test_path_log_and_time_carry_their_values() -> None:
    path = fg.poses_in_frame(np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]]), T_NS, frame_id="world")
    assert [p["position"] for p in path["poses"]] == [{"x": 0.1, "y": 0.2, "z": 0.3}, {"x": 0.4, "y": 0.5, "z": 0.6}]
    assert all(p["orientation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0} for p in path["poses"])
    with pytest.raises(InputError, match=r"\(n, 3\)"):
        fg.poses_in_frame(np.zeros((2, 2)), T_NS)
    log = fg.log_message(T_NS, "warning", "statement 3: refused", "robot")
    assert (log["level"], log["message"], log["name"]) == (3, "statement 3: refused", "robot")
    assert [fg.log_message(T_NS, lv, "", "")["level"] for lv in ("debug", "info", "error")] == [1, 2, 4]
    with pytest.raises(UnknownNameError, match="warning"):
        fg.log_message(T_NS, "warn", "", "")
    assert fg.stamp(0) == {"sec": 0, "nsec": 0} and fg.stamp(2_999_999_999) == {"sec": 2, "nsec": 999_999_999}
    with pytest.raises(InputError, match="1970"):
        fg.stamp(-1)


# -- the validator is not vacuous -----------------------------------------------------------------
def test_broken_messages_fail_validation_naming_where(cells) -> None:
    cell = cells["puma562_empty.toml"]
    good = fg.frame_transforms(cell.robot, cell.q_home, cell.world_T_base, "virtual", T_NS)
    broken = copy.deepcopy(good)
    del broken["transforms"][2]["rotation"]["w"]
    with pytest.raises(FoxgloveSchemaError, match=r"transforms\[2\]\.rotation"):
        validate("foxglove.FrameTransforms", broken)
    broken = copy.deepcopy(good)
    broken["transforms"][0]["timestamp"] = {"sec": 1, "nsec": 1_000_000_000}
    with pytest.raises(FoxgloveSchemaError, match=r"transforms\[0\]\.timestamp\.nsec"):
        validate("foxglove.FrameTransforms", broken)
    scene = fg.scene_update(cell, {}, T_NS)
    scene["entities"][1]["cylinders"][0]["size"]["z"] = "0.1 m"
    with pytest.raises(FoxgloveSchemaError, match=r"entities\[1\]\.cylinders\[0\]\.size\.z"):
        validate("foxglove.SceneUpdate", scene)
    log = fg.log_message(T_NS, "info", "hello", "console")
    with pytest.raises(FoxgloveSchemaError, match=r"\$\.level"):
        validate("foxglove.Log", {**log, "level": 7})
    with pytest.raises(FoxgloveSchemaError, match=r"\$: 'file' is a required property"):
        validate("foxglove.Log", {k: v for k, v in log.items() if k != "file"})
    with pytest.raises(FoxgloveSchemaError, match=r"poses\[0\]\.position\.x: .*numpy"):
        validate("foxglove.PosesInFrame", {**fg.poses_in_frame(np.zeros((1, 3)), T_NS),
                                          "poses": [{"position": {"x": np.float64(0.0), "y": 0.0, "z": 0.0},
                                                     "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}]})
