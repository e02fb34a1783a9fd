"""Robots load from data files; broken files are rejected with the file and the field."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.errors import FileFormatError, InputError, JointLimitError, UnknownNameError
from shared.robots.loader import load_robot
from shared.spatial import rot_x, rot_z

PUMA_TOML = """
name = "mini"
ik = "dls"
[kinematics]
convention = "modified"
length_unit = "mm"
angle_unit = "deg"
[[kinematics.joints]]
a = 0.0
alpha = 0.0
d = 0.0
limits = [-90.0, 90.0]
[[kinematics.joints]]
a = 100.0
alpha = 0.0
d = 0.0
limits = [-90.0, 90.0]
"""


def modified_dh_fk(robot, q: np.ndarray) -> np.ndarray:
    """Plain numpy product of modified-DH link transforms (Craig), independent of pinocchio."""
    out = np.eye(4)
    for joint, qi in zip(robot.description.joints, q):
        a = np.eye(4)
        a[:3, :3] = rot_x(joint.alpha)
        a[0, 3] = joint.a
        b = np.eye(4)
        b[:3, :3] = rot_z(joint.sign * qi + joint.offset)
        b[2, 3] = joint.d
        out = out @ a @ b
    return out @ robot.description.flange_T_tool


def test_puma_matches_table_4_1() -> None:
    robot = load_robot("puma562")
    assert robot.dof == 6
    np.testing.assert_allclose(np.degrees(robot.lower), [-160, -205, -45, -110, -100, -266])
    np.testing.assert_allclose(np.degrees(robot.upper), [160, 45, 225, 170, 100, 266])
    d = robot.description.joints
    assert d[1].d == pytest.approx(0.14406)
    assert d[2].a == pytest.approx(0.431815)
    assert d[3].a == pytest.approx(-0.02041)
    assert d[3].d == pytest.approx(0.43263)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6))
def test_puma_fk_equals_modified_dh_product(fractions: list[float]) -> None:
    robot = load_robot("puma562")
    q = robot.lower + (np.array(fractions) + 1.0) / 2.0 * (robot.upper - robot.lower)
    np.testing.assert_allclose(robot.fk(q), modified_dh_fk(robot, q), atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6))
def test_jacobian_matches_finite_differences(values: list[float]) -> None:
    robot = load_robot("puma562")
    q = np.array(values)
    jac = robot.jacobian(q)
    eps = 1e-7
    base = robot.fk(q)
    for i in range(robot.dof):
        dq = np.zeros(robot.dof)
        dq[i] = eps
        moved = robot.fk(q + dq)
        np.testing.assert_allclose((moved[:3, 3] - base[:3, 3]) / eps, jac[:3, i], atol=1e-5)
        skew = (moved[:3, :3] @ base[:3, :3].T - np.eye(3)) / eps
        np.testing.assert_allclose([skew[2, 1], skew[0, 2], skew[1, 0]], jac[3:, i], atol=1e-5)


def test_link_poses_end_at_the_tool() -> None:
    robot = load_robot("puma562")
    q = np.radians([10, -20, 30, 40, 50, 60])
    poses = robot.link_poses(q)
    assert poses.shape == (7, 4, 4)
    np.testing.assert_allclose(poses[0], np.eye(4))
    np.testing.assert_allclose(poses[6] @ robot.description.flange_T_tool, robot.fk(q), atol=1e-12)


def test_models_are_loaded_once() -> None:
    assert load_robot("puma562") is load_robot("puma562")


def test_unknown_robot_lists_the_choices() -> None:
    with pytest.raises(UnknownNameError, match="puma562"):
        load_robot("puma")


def test_joint_vector_length_and_limits_are_checked() -> None:
    robot = load_robot("puma562")
    with pytest.raises(InputError, match="6 joints, got 3"):
        robot.as_q([0, 0, 0])
    with pytest.raises(InputError, match="NaN"):
        robot.as_q([0, 0, 0, 0, 0, float("nan")])
    with pytest.raises(JointLimitError, match="joint 2"):
        robot.check_limits(np.radians([0, 60, 0, 0, 0, 0]))


def test_toml_robot_file_loads(tmp_path) -> None:
    path = tmp_path / "mini.toml"
    path.write_text(PUMA_TOML)
    robot = load_robot(path)
    np.testing.assert_allclose(robot.fk(np.radians([90, 0]))[:3, 3], [0.0, 0.1, 0.0], atol=1e-12)


@pytest.mark.parametrize(
    ("edit", "field", "message"),
    [
        (lambda s: s.replace('convention = "modified"', 'convention = "weird"'), "kinematics.convention", "modified"),
        (lambda s: s.replace("limits = [-90.0, 90.0]\n[[", "limits = [90.0, -90.0]\n[["), "kinematics.joints[0].limits", "below"),
        (lambda s: s.replace("a = 100.0", "a = \"far\""), "kinematics.joints[1].a", "number"),
        (lambda s: s + "\n[[geometry]]\nlink = 5\nshape = \"sphere\"\nradius = 1.0\n", "geometry[0].link", "does not exist"),
        (lambda s: s + "\n[[geometry]]\nlink = 1\nshape = \"box\"\n", "geometry[0].size", "needs 'size'"),
        (lambda s: s + "\nsurprise = 1\n", "surprise", "Extra"),
        (lambda s: s.replace("[kinematics]", "[kinematics"), None, "not valid TOML"),
    ],
)
def test_broken_robot_files_name_file_and_field(tmp_path, edit, field, message) -> None:
    path = tmp_path / "broken.toml"
    path.write_text(edit(PUMA_TOML))
    with pytest.raises(FileFormatError) as info:
        load_robot(path)
    text = str(info.value)
    assert str(path) in text
    if field:
        assert field in text
    assert message in text


def test_missing_robot_file(tmp_path) -> None:
    with pytest.raises(FileFormatError, match="does not exist"):
        load_robot(tmp_path / "nothing.toml")
