"""URDF robots: the UR5 loads with the DH robots' interface, its kinematics match the UR5's
published geometry, damped-least-squares IK round-trips, and broken files get one clear line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from shared.errors import FileFormatError
from shared.paths import ASSETS_DIR
from shared.robots.ik import solve_ik
from shared.robots.ik_dls import dls_ik_all
from shared.robots.loader import load_robot
from shared.robots.shapes import link_meshes
from shared.robots.urdf import load_urdf_robot
from shared.spatial import matrix_to_rpy, pose_to_transform, rot_x, rot_z

UR5 = ASSETS_DIR / "robots" / "ur5" / "ur5_robot.urdf"
#: UR5 standard DH parameters (Universal Robots): d (m), a (m), alpha (rad) per joint
UR5_D = (0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823)
UR5_A = (0.0, -0.425, -0.39225, 0.0, 0.0, 0.0)
UR5_ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)
#: URDF angles are written with 11 decimals (1.57079632679), so frames differ from exact DH by ~1e-11
GEOMETRY_TOL = 1e-9


def ur5_dh_fk(q: np.ndarray) -> np.ndarray:
    """``base_link_T_tool0`` from the UR5 DH table, plain numpy: the DH base frame is UR's
    ``base``, turned 180 deg about z from ``base_link``; DH frame 6 is ``tool0``."""
    out = np.eye(4)
    out[:3, :3] = rot_z(np.pi)
    for qi, d, a, alpha in zip(q, UR5_D, UR5_A, UR5_ALPHA):
        step = np.eye(4)
        step[:3, :3] = rot_z(qi) @ rot_x(alpha)
        step[:3, 3] = [a * np.cos(qi), a * np.sin(qi), d]
        out = out @ step
    return out


def pinocchio_tool0(q: np.ndarray) -> np.ndarray:
    """``tool0`` straight from pinocchio's own URDF reader, without the teleprog loader."""
    model = pin.buildModelFromUrdf(str(UR5))
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId("tool0")].homogeneous


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "server.cli", *args], capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def ur5():
    return load_robot(UR5)


# -- loading and interface ---------------------------------------------------------------------
def test_ur5_loads_with_joint_ranges_tool_and_links(ur5) -> None:
    assert ur5.name == "ur5"
    assert ur5.dof == 6
    assert ur5.description.ik == "dls"
    assert ur5.description.convention is None
    assert ur5.description.urdf_tool_frame == "tool0"
    assert ur5.joint_names == (
        "shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint",
    )
    np.testing.assert_allclose(np.degrees(ur5.upper), [360, 360, 180, 360, 360, 360], atol=1e-8)
    np.testing.assert_allclose(ur5.lower, -ur5.upper)
    np.testing.assert_allclose(ur5.description.lower, ur5.lower)
    assert ur5.description.link_names[0] == "world"
    assert ur5.description.link_names[-1] == "wrist_3_link"
    assert load_robot(str(UR5)) is ur5  # cached like the built-in robots


def test_ur5_shapes_are_the_collision_meshes(ur5) -> None:
    meshes = {Path(s.mesh_path).name for shapes in ur5.shapes.values() for s in shapes if s.kind == "mesh"}
    assert meshes == {"base.stl", "shoulder.stl", "upperarm.stl", "forearm.stl", "wrist1.stl", "wrist2.stl", "wrist3.stl"}
    assert set(ur5.shapes) == set(range(7))
    for link in range(7):
        mesh = link_meshes(ur5.shapes[link])
        assert mesh is not None and len(mesh.faces) > 100
    # ee_link's 1 cm box hangs from wrist_3_link 0.0823 m along its y axis, turned 90 deg about z
    (box,) = [s for s in ur5.shapes[6] if s.kind == "box"]
    np.testing.assert_allclose(box.link_T_shape[:3, 3], [0.0, 0.0823 - 0.01, 0.0], atol=1e-9)


def test_link_poses_and_tool_agree(ur5) -> None:
    q = np.radians([10.0, -20.0, 30.0, 40.0, 50.0, 60.0])
    poses = ur5.link_poses(q)
    assert poses.shape == (7, 4, 4)
    np.testing.assert_allclose(poses[0], np.eye(4))
    wrist3_T_tool0 = pose_to_transform(np.array([0.0, 0.0823, 0.0]), np.array([-np.pi / 2, 0.0, 0.0]))
    np.testing.assert_allclose(poses[6] @ wrist3_T_tool0, ur5.fk(q), atol=1e-10)
    np.testing.assert_allclose(poses[1][:3, 3], [0.0, 0.0, 0.089159], atol=1e-12)  # shoulder height d1


# -- forward kinematics against the UR5's published geometry -------------------------------------
def test_zero_pose_matches_ur5_geometry(ur5) -> None:
    base_T_tool = ur5.fk(np.zeros(6))
    # stretched out along +x of base_link: |a2 + a3| forward, d4 + d6 sideways, d1 - d5 up
    np.testing.assert_allclose(base_T_tool[:3, 3], [0.81725, 0.19145, 0.089159 - 0.09465], atol=GEOMETRY_TOL)
    np.testing.assert_allclose(base_T_tool[:3, :3], [[-1, 0, 0], [0, 0, 1], [0, 1, 0]], atol=GEOMETRY_TOL)
    np.testing.assert_allclose(base_T_tool, ur5_dh_fk(np.zeros(6)), atol=GEOMETRY_TOL)
    np.testing.assert_allclose(base_T_tool, pinocchio_tool0(np.zeros(6)), atol=1e-15)


def test_another_pose_matches_dh_and_pinocchio(ur5) -> None:
    q = np.radians([30.0, -60.0, 90.0, -45.0, 20.0, 70.0])
    np.testing.assert_allclose(ur5.fk(q), ur5_dh_fk(q), atol=GEOMETRY_TOL)
    np.testing.assert_allclose(ur5.fk(q), pinocchio_tool0(q), atol=1e-15)
    # arm straight up (shoulder lift -90 deg, rest 0): tool0 at height d1 + |a2 + a3|, d5 forward
    up = ur5.fk(np.radians([0.0, -90.0, 0.0, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(up[:3, 3], [0.09465, 0.19145, 0.089159 + 0.81725], atol=GEOMETRY_TOL)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-2 * np.pi, 2 * np.pi), min_size=6, max_size=6))
def test_fk_equals_ur5_dh_table_everywhere(values: list[float]) -> None:
    q = np.array(values)
    np.testing.assert_allclose(load_robot(UR5).fk(q), ur5_dh_fk(q), atol=GEOMETRY_TOL)


def test_jacobian_matches_finite_differences(ur5) -> None:
    q = np.radians([15.0, -70.0, 80.0, -30.0, 45.0, 10.0])
    jac = ur5.jacobian(q)
    base = ur5.fk(q)
    eps = 1e-7
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = eps
        moved = ur5.fk(q + dq)
        np.testing.assert_allclose((moved[:3, 3] - base[:3, 3]) / eps, jac[:3, i], atol=1e-5)


# -- inverse kinematics ----------------------------------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=6, max_size=6))
@example(values=[0.0, 0.0, 0.5, -2.0, 6.103515625e-05, 0.0])  # wrist 60 microradians from singular
def test_ik_then_fk_reaches_the_target(values: list[float]) -> None:
    robot = load_robot(UR5)
    q = np.array(values)
    # DLS can stall where two singularities meet (arm stretched to the workspace boundary AND
    # wrist axes 4 and 6 aligned): keep configurations off that set; single singularities are
    # covered below
    assume(not (np.min(np.abs(np.sin([q[2], q[4]]))) < 1e-2 and np.max(np.abs(np.sin([q[2], q[4]]))) < 5e-2))
    target = robot.fk(q).copy()
    solutions = solve_ik(robot, target)
    assert solutions, "no solution for a pose the arm reaches"
    for s in solutions:
        assert robot.within_limits(s)
        reached = robot.fk(s)
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-6
        assert np.linalg.norm(pin.log3(reached[:3, :3] @ target[:3, :3].T)) < 1e-6
    # nearest-first: asked near the pose it came from, the first solution is that pose
    near = solve_ik(robot, target, q_near=q)
    np.testing.assert_allclose(near[0], q, atol=1e-6)


@pytest.mark.parametrize(
    "q_deg",
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],  # stretched arm and aligned wrist: the zero pose
        [25.0, -40.0, 0.0, 60.0, 35.0, -80.0],  # stretched arm: the target is on the reach boundary
        [25.0, -40.0, 70.0, 60.0, 0.0, -80.0],  # wrist singular: axes 4 and 6 aligned
        [25.0, -40.0, 70.0, 60.0, 0.002, -80.0],  # wrist nearly singular (35 microradians)
        [-120.0, -100.0, 180.0, 10.0, 45.0, 5.0],  # elbow folded back completely
    ],
)
def test_singular_configurations_are_solved(ur5, q_deg: list[float]) -> None:
    target = ur5.fk(np.radians(q_deg)).copy()
    solutions = solve_ik(ur5, target)
    assert solutions
    for s in solutions[:: max(1, len(solutions) // 8)]:
        reached = ur5.fk(s)
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-6
        assert np.linalg.norm(pin.log3(reached[:3, :3] @ target[:3, :3].T)) < 1e-6


def test_dls_finds_several_distinct_arm_configurations(ur5) -> None:
    target = ur5.fk(np.radians([20.0, -70.0, 100.0, -120.0, 60.0, 30.0])).copy()
    raw = dls_ik_all(ur5, target, np.zeros(6))
    assert len(raw) >= 4  # the UR5 has 8 for this pose
    for i, a in enumerate(raw):
        assert np.all(np.abs(a) <= np.pi)
        for b in raw[:i]:
            assert np.max(np.abs(a - b)) > 1e-3
    again = dls_ik_all(ur5, target, np.zeros(6))
    assert len(again) == len(raw) and all(np.array_equal(a, b) for a, b in zip(raw, again))  # deterministic


def test_unreachable_pose_has_no_solution(ur5) -> None:
    assert solve_ik(ur5, pose_to_transform(np.array([2.0, 0.0, 0.5]), np.zeros(3))) == []


# -- command line ------------------------------------------------------------------------------------
def test_cli_fk_of_the_ur5(ur5) -> None:
    out = run_cli("kin", "fk", "--robot", str(UR5), "--deg", "30", "-60", "90", "-45", "20", "70", "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["unit"] == "m"
    expected = ur5_dh_fk(np.radians([30.0, -60.0, 90.0, -45.0, 20.0, 70.0]))
    np.testing.assert_allclose(data["position"], expected[:3, 3], atol=GEOMETRY_TOL)
    np.testing.assert_allclose(data["rotation"], expected[:3, :3], atol=GEOMETRY_TOL)


def test_cli_ik_of_the_ur5(ur5) -> None:
    q_deg = np.array([30.0, -60.0, 90.0, -45.0, 20.0, 70.0])
    target = ur5.fk(np.radians(q_deg))
    xyz = target[:3, 3]
    rpy = np.degrees(matrix_to_rpy(target[:3, :3]))
    out = run_cli(
        "kin", "ik", "--robot", str(UR5), "--xyz", *(repr(float(v)) for v in xyz), "--rpy", *(repr(float(v)) for v in rpy),
        "--near", *(repr(float(v)) for v in q_deg), "--json",
    )
    assert out.returncode == 0, out.stderr
    solutions = np.array(json.loads(out.stdout)["solutions"])
    assert solutions.shape[1] == 6
    np.testing.assert_allclose(solutions[0], q_deg, atol=1e-5)
    for s in solutions:
        reached = ur5.fk(np.radians(s))
        assert np.linalg.norm(reached[:3, 3] - xyz) < 1e-6
    # one line per posture: no two differ by whole turns only; --all-turns lists every variant
    wrapped = (solutions + 180.0) % 360.0 - 180.0
    assert len(np.unique(np.round(wrapped, 3), axis=0)) == len(solutions) <= 8
    variants = json.loads(out.stdout)["turn_variants"]
    everything = run_cli(
        "kin", "ik", "--robot", str(UR5), "--xyz", *(repr(float(v)) for v in xyz), "--rpy", *(repr(float(v)) for v in rpy),
        "--all-turns", "--json",
    )
    assert len(json.loads(everything.stdout)["solutions"]) == sum(variants) > len(solutions)


def test_cli_broken_urdf_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'>")
    out = run_cli("kin", "fk", "--robot", str(bad), "--deg", "0")
    assert out.returncode == 1
    assert "Traceback" not in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
    assert str(bad) in out.stderr and "not valid XML" in out.stderr


# -- broken files ------------------------------------------------------------------------------------
TWO_JOINTS = """<?xml version="1.0"?>
<robot name="two">
  <link name="base"/>
  <link name="l1"><collision><geometry><cylinder radius="0.05" length="0.3"/></geometry></collision></link>
  <link name="l2"><collision><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.05 0.05"/></geometry></collision></link>
  <link name="tip"/>
  <joint name="j1" type="{j1_type}">
    <parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-1.5" upper="1.5" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="continuous">
    <parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
  </joint>
  <joint name="fixed_tip" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.2 0 0"/></joint>
  {extra}
</robot>
"""


def write(tmp_path: Path, text: str, name: str = "robot.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_small_urdf_continuous_joint_and_default_tool(tmp_path: Path) -> None:
    robot = load_urdf_robot(write(tmp_path, TWO_JOINTS.format(j1_type="revolute", extra="")))
    assert robot.dof == 2
    assert robot.description.urdf_tool_frame == "tip"
    np.testing.assert_allclose(robot.lower, [-1.5, -2 * np.pi])
    np.testing.assert_allclose(robot.upper, [1.5, 2 * np.pi])
    # j2 turns the 0.2 m arm about y: at j2 = 90 deg the tip points down (-z)
    np.testing.assert_allclose(robot.fk(np.array([0.0, np.pi / 2]))[:3, 3], [0.0, 0.0, 0.2], atol=1e-12)
    (box,) = robot.shapes[2]
    np.testing.assert_allclose(box.size, (0.2, 0.05, 0.05))
    named = load_urdf_robot(write(tmp_path, TWO_JOINTS.format(j1_type="revolute", extra="")), tool_link="l1")
    np.testing.assert_allclose(named.fk(np.array([0.0, 1.0]))[:3, 3], [0.0, 0.0, 0.1])


@pytest.mark.parametrize(
    ("text", "tool", "message"),
    [
        (None, None, "file does not exist"),
        ("<robot name='x'><link name='a'></robot>", None, "not valid XML"),
        ("<model name='x'/>", None, "needs <robot>"),
        (TWO_JOINTS.format(j1_type="fixed", extra="").replace('type="continuous"', 'type="fixed"'), None,
         "no revolute or continuous joints"),
        (TWO_JOINTS.format(j1_type="prismatic", extra=""), None, "is prismatic"),
        (TWO_JOINTS.format(j1_type="revolute", extra=""), "hand", "tool link 'hand' is not a link"),
        (TWO_JOINTS.format(j1_type="revolute", extra="").replace('<box size="0.2 0.05 0.05"/>', '<mesh filename="meshes/gone.stl"/>'),
         None, "mesh file 'meshes/gone.stl' not found"),
        (TWO_JOINTS.format(j1_type="revolute", extra="").replace('<parent link="l1"/>', '<parent link="nowhere"/>'), None,
         "parent link 'nowhere' is not defined"),
        (TWO_JOINTS.format(j1_type="revolute", extra="").replace('lower="-1.5"', 'lower="2"'), None, "must be below upper"),
        (TWO_JOINTS.format(
            j1_type="revolute",
            extra='<link name="finger"/><joint name="jf" type="revolute"><parent link="l1"/><child link="finger"/>'
                  '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'),
         None, "one serial chain"),
    ],
    ids=["missing", "bad-xml", "not-robot", "no-revolute", "prismatic", "unknown-tool", "missing-mesh", "bad-parent",
         "bad-limits", "branching"],
)
def test_broken_urdf_gives_one_clear_line(tmp_path: Path, text: str | None, tool: str | None, message: str) -> None:
    path = tmp_path / "robot.urdf" if text is None else write(tmp_path, text)
    with pytest.raises(FileFormatError) as caught:
        load_urdf_robot(path, tool_link=tool)
    text_of = str(caught.value)
    assert message in text_of
    assert str(path) in text_of
    assert "\n" not in text_of


def test_broken_urdf_through_the_loader_names_the_file(tmp_path: Path) -> None:
    path = write(tmp_path, TWO_JOINTS.format(j1_type="planar", extra=""), "planar.urdf")
    with pytest.raises(FileFormatError, match=r"planar\.urdf: joint 'j1': is planar"):
        load_robot(path)


def test_package_uri_meshes_resolve_from_parent_folders(tmp_path: Path) -> None:
    package = tmp_path / "my_arm"
    (package / "urdf").mkdir(parents=True)
    (package / "meshes").mkdir()
    (package / "meshes" / "link.stl").write_bytes((UR5.parent / "meshes" / "wrist3.stl").read_bytes())
    text = TWO_JOINTS.format(j1_type="revolute", extra="").replace(
        '<box size="0.2 0.05 0.05"/>', '<mesh filename="package://my_arm/meshes/link.stl" scale="2 2 2"/>'
    )
    robot = load_urdf_robot(write(package / "urdf", text))
    (shape,) = robot.shapes[2]
    assert shape.kind == "mesh" and Path(shape.mesh_path) == (package / "meshes" / "link.stl").resolve()
    assert shape.scale == (2.0, 2.0, 2.0)
    np.testing.assert_allclose(shape.link_T_shape[:3, 3], [0.1, 0.0, 0.0])


def test_unused_urdf_parts_neither_fail_nor_print(tmp_path: Path) -> None:
    """Inertia, visuals and gazebo tags are not read: junk there neither fails nor prints."""
    junk = '<inertial><mass value="heavy"/></inertial><visual><geometry><torus/></geometry></visual>'
    text = TWO_JOINTS.format(j1_type="revolute", extra="<gazebo><anything/></gazebo>").replace(
        '<link name="l1">', f'<link name="l1">{junk}'
    )
    path = write(tmp_path, text)
    out = run_cli("kin", "fk", "--robot", str(path), "--deg", "0", "90", "--json")
    assert out.returncode == 0, out.stderr
    assert out.stderr == ""
    np.testing.assert_allclose(json.loads(out.stdout)["position"], [0.0, 0.0, 0.2], atol=1e-12)
