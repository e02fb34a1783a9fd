"""Closed-form PUMA IK: every solution reproduces the pose, the original q is among them, and the
singular and unreachable cases behave (checked against pinocchio's forward kinematics)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from shared.errors import InputError
from shared.robots.description import DHJoint, RobotDescription
from shared.robots.ik import solve_ik
from shared.robots.ik_puma import puma_ik_all
from shared.robots.loader import load_robot
from shared.robots.model import Robot, build_dh_model

POS_TOL = 1e-9  # m
ROT_TOL = 1e-9  # rad
Q_TOL = 1e-6  # rad

fractions6 = st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6)
angles6 = st.lists(st.floats(-math.pi, math.pi), min_size=6, max_size=6)


def puma() -> Robot:
    return load_robot("puma562")


def make_robot(joints: list[DHJoint], name: str = "custom") -> Robot:
    desc = RobotDescription(
        name=name, source="test", convention="modified", joints=tuple(joints),
        flange_T_tool=np.eye(4), ik="puma",
    )
    model, tool_id, link_ids = build_dh_model(desc)
    return Robot(desc, model, tool_id, link_ids)


def wrapped(x: np.ndarray) -> np.ndarray:
    return np.pi - np.mod(np.pi - x, 2.0 * np.pi)


def angle_error(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(wrapped(np.asarray(a) - np.asarray(b)))))


def pose_error(robot: Robot, q: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    reached = robot.fk(q)
    pos = float(np.max(np.abs(reached[:3, 3] - target[:3, 3])))
    rot = float(np.linalg.norm(pin.log3(reached[:3, :3].T @ target[:3, :3])))
    return pos, rot


def assert_all_reproduce(robot: Robot, solutions: list[np.ndarray], target: np.ndarray) -> None:
    assert solutions, "expected at least one solution"
    for q in solutions:
        assert q.shape == (robot.dof,)
        assert np.all(np.isfinite(q)), q
        pos, rot = pose_error(robot, q, target)
        assert pos < POS_TOL and rot < ROT_TOL, (np.degrees(q), pos, rot)


def contains(solutions: list[np.ndarray], q: np.ndarray, tol: float = Q_TOL) -> bool:
    return any(angle_error(s, q) < tol for s in solutions)


def puma_geometry(robot: Robot) -> dict[str, float]:
    j = robot.description.joints
    return {"h": j[1].d + j[2].d, "a2": j[2].a, "a3": j[3].a, "d4": j[3].d, "phi": math.atan2(j[3].d, j[3].a)}


def generic(robot: Robot, q: np.ndarray, margin: float = 1e-3) -> bool:
    """q is away from the wrist, elbow and shoulder singularities (PUMA table, no offsets)."""
    g = puma_geometry(robot)
    wrist = robot.fk(q)[:3, 3]
    return (
        abs(math.sin(q[4])) > margin
        and abs(math.sin(q[2] - g["phi"])) > margin
        and wrist[0] ** 2 + wrist[1] ** 2 - g["h"] ** 2 > margin**2
    )


# -- the PUMA of Table 4.1 -------------------------------------------------------------------


@settings(max_examples=300, deadline=None)
@given(fractions6)
def test_random_q_within_limits_is_recovered(fractions: list[float]) -> None:
    robot = puma()
    q = robot.lower + np.array(fractions) * (robot.upper - robot.lower)
    assume(abs(math.sin(q[4])) > 1e-6)  # at the wrist singularity q4, q6 are not unique
    target = robot.fk(q).copy()
    solutions = solve_ik(robot, target)
    assert contains(solutions, q), (np.degrees(q), [np.degrees(s) for s in solutions])
    assert_all_reproduce(robot, solutions, target)
    assert all(robot.within_limits(s) for s in solutions)


@settings(max_examples=300, deadline=None)
@given(angles6)
def test_generic_pose_has_eight_solutions(values: list[float]) -> None:
    robot = puma()
    q = np.array(values)
    assume(generic(robot, q))
    target = robot.fk(q).copy()
    solutions = solve_ik(robot, target, respect_limits=False)
    assert len(solutions) == 8
    assert contains(solutions, q)
    assert_all_reproduce(robot, solutions, target)
    raw = puma_ik_all(robot.description.joints, target)
    assert len(raw) == 8
    assert all(np.all(s > -np.pi) and np.all(s <= np.pi) for s in raw)


def test_unreachable_targets_give_no_solution() -> None:
    robot = puma()
    far = np.eye(4)
    far[:3, 3] = [2.0, 0.0, 0.0]
    assert solve_ik(robot, far) == []
    assert puma_ik_all(robot.description.joints, far) == []
    # the wrist centre can never be closer than d2 to the joint-1 axis
    on_axis = np.eye(4)
    on_axis[:3, 3] = [0.0, 0.0, 0.5]
    assert solve_ik(robot, on_axis, respect_limits=False) == []
    # too close to the shoulder for the elbow to fold that far
    near = np.eye(4)
    near[:3, 3] = [0.0, puma_geometry(robot)["h"], 0.0]
    assert solve_ik(robot, near, respect_limits=False) == []


@pytest.mark.parametrize("q5", [0.0, 1e-13, -1e-14, np.pi])
@settings(max_examples=60, deadline=None)
@given(angles6)
def test_wrist_singularity_gives_finite_solutions(q5: float, values: list[float]) -> None:
    robot = puma()
    q = np.array(values)
    q[4] = q5
    target = robot.fk(q).copy()
    solutions = solve_ik(robot, target, respect_limits=False)
    assert_all_reproduce(robot, solutions, target)
    singular = [s for s in solutions if abs(math.sin(s[4])) < 1e-9]
    assert singular, "the arm configuration of q has a singular wrist"
    # a singular wrist gives one representative, with q4 = 0; the other arm configurations
    # generally have a regular wrist and two solutions each
    # (only checked for an exactly singular wrist: at |q5| ~ 1e-13 rounding may leave the wrist
    # just regular, and then q4 is whatever the regular formula gives)
    if q5 in (0.0, np.pi):
        assert all(abs(s[3]) < 1e-12 for s in singular)
    g = puma_geometry(robot)
    wrist = target[:3, 3]
    if wrist[0] ** 2 + wrist[1] ** 2 - g["h"] ** 2 > 1e-6 and abs(math.sin(q[2] - g["phi"])) > 1e-3:
        assert len(solutions) == 8 - len(singular)
    combo = (lambda v: v[3] + v[5]) if q5 != np.pi else (lambda v: v[5] - v[3])
    assert any(
        angle_error(s[[0, 1, 2, 4]], q[[0, 1, 2, 4]]) < Q_TOL and angle_error(combo(s), combo(q)) < Q_TOL
        for s in singular
    )


def test_wrist_singularity_uses_the_requested_q4() -> None:
    robot = puma()
    q = np.radians([20.0, -30.0, 40.0, 50.0, 0.0, 60.0])
    target = robot.fk(q).copy()
    solutions = puma_ik_all(robot.description.joints, target, q4_singular=q[3])
    assert contains(solutions, q)
    assert_all_reproduce(robot, solutions, target)


def test_near_wrist_singularity_is_exact() -> None:
    robot = puma()
    # just above WRIST_SINGULAR the wrist is regular: all eight solutions, each exact
    for q5 in (1e-8, 1e-7, 1e-5):
        q = np.radians([20.0, -30.0, 40.0, 50.0, 0.0, 60.0])
        q[4] = q5
        target = robot.fk(q).copy()
        solutions = solve_ik(robot, target, respect_limits=False)
        assert len(solutions) == 8
        assert_all_reproduce(robot, solutions, target)
    # below it the wrist counts as singular (one representative per arm configuration), and
    # the representatives still reproduce the target
    q = np.radians([20.0, -30.0, 40.0, 50.0, 0.0, 60.0])
    q[4] = 1e-11
    target = robot.fk(q).copy()
    solutions = solve_ik(robot, target, respect_limits=False)
    assert 4 <= len(solutions) < 8
    assert_all_reproduce(robot, solutions, target)


def test_elbow_fully_stretched_gives_one_elbow_solution() -> None:
    robot = puma()
    q = np.array([0.3, -0.7, puma_geometry(robot)["phi"], 0.4, 0.5, 0.6])
    target = robot.fk(q).copy()
    solutions = solve_ik(robot, target, respect_limits=False)
    assert len(solutions) == 4
    assert contains(solutions, q)
    assert_all_reproduce(robot, solutions, target)


def test_wrist_centre_on_the_shoulder_cylinder_gives_one_shoulder_solution() -> None:
    """With d2 != 0 the wrist centre cannot reach the joint-1 axis; on the cylinder of radius d2
    around it the two shoulder solutions coincide."""
    robot = puma()
    g = puma_geometry(robot)
    theta3 = 0.4
    big_x = g["a2"] + g["a3"] * math.cos(theta3) + g["d4"] * math.sin(theta3)
    big_y = g["a3"] * math.sin(theta3) - g["d4"] * math.cos(theta3)
    theta2 = math.atan2(big_x, big_y)  # r = c2 X - s2 Y = 0
    q = np.array([0.2, theta2, theta3, 0.4, 0.5, 0.6])
    target = robot.fk(q).copy()
    assert math.hypot(target[0, 3], target[1, 3]) == pytest.approx(g["h"], abs=1e-12)
    solutions = solve_ik(robot, target, respect_limits=False)
    assert len(solutions) == 4
    assert contains(solutions, q)
    assert_all_reproduce(robot, solutions, target)


@settings(max_examples=100, deadline=None)
@given(fractions6, st.lists(st.floats(-0.2, 0.2), min_size=6, max_size=6))
def test_solutions_are_sorted_nearest_first(fractions: list[float], noise: list[float]) -> None:
    robot = puma()
    q = robot.lower + np.array(fractions) * (robot.upper - robot.lower)
    assume(abs(math.sin(q[4])) > 1e-3)
    q_near = np.clip(q + np.array(noise), robot.lower, robot.upper)
    solutions = solve_ik(robot, robot.fk(q).copy(), q_near=q_near)
    distances = [float(np.sum((s - q_near) ** 2)) for s in solutions]
    assert distances == sorted(distances)
    if generic(robot, q, margin=0.3):
        assert angle_error(solutions[0], q) < Q_TOL


# -- other PUMA-type tables ------------------------------------------------------------------


def general_puma_joints() -> list[DHJoint]:
    """The Table 4.1 structure with offsets, reversed joints and d1, d3, d6 non-zero."""
    deg = math.radians
    return [
        DHJoint(a=0.0, alpha=0.0, d=0.3, offset=deg(30), sign=-1),
        DHJoint(a=0.0, alpha=deg(-90), d=0.1, offset=deg(-90)),
        DHJoint(a=0.4, alpha=0.0, d=0.05, offset=deg(10), sign=-1),
        DHJoint(a=0.03, alpha=deg(90), d=0.38, offset=deg(180)),
        DHJoint(a=0.0, alpha=deg(-90), d=0.0, offset=deg(5), sign=-1),
        DHJoint(a=0.0, alpha=deg(90), d=0.07, offset=deg(-45)),
    ]


@settings(max_examples=200, deadline=None)
@given(angles6)
def test_offsets_signs_and_extra_lengths_are_honoured(values: list[float]) -> None:
    robot = make_robot(general_puma_joints())
    q = np.array(values)
    theta5 = -q[4] + math.radians(5)
    assume(abs(math.sin(theta5)) > 1e-6)
    target = robot.fk(q).copy()
    solutions = solve_ik(robot, target, respect_limits=False)
    assert contains(solutions, q)
    assert_all_reproduce(robot, solutions, target)


@settings(max_examples=60, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(-math.pi, math.pi), st.floats(-math.pi, math.pi))
def test_shoulder_singularity_gives_finite_solutions(theta3: float, q4: float, q6: float) -> None:
    """With no shoulder offset (d2 = 0) and the wrist centre on the joint-1 axis, q1 is free."""
    joints = list(puma().description.joints)
    joints[1] = dataclasses.replace(joints[1], d=0.0)
    robot = make_robot(joints)
    a2, a3, d4 = joints[2].a, joints[3].a, joints[3].d
    big_x = a2 + a3 * math.cos(theta3) + d4 * math.sin(theta3)
    big_y = a3 * math.sin(theta3) - d4 * math.cos(theta3)
    assume(math.hypot(big_x, big_y) > 1e-3)
    theta2 = math.atan2(big_x, big_y)
    q = np.array([0.7, theta2, theta3, q4, 0.5, q6])
    target = robot.fk(q).copy()
    assert math.hypot(target[0, 3], target[1, 3]) < 1e-12
    solutions = solve_ik(robot, target, respect_limits=False)
    assert_all_reproduce(robot, solutions, target)
    assert all(abs(s[0]) < 1e-12 for s in solutions)  # the representative keeps q1 = 0


# -- input checks ----------------------------------------------------------------------------


def _replace(index: int, **changes: float) -> list[DHJoint]:
    joints = list(puma().description.joints)
    joints[index] = dataclasses.replace(joints[index], **changes)
    return joints


@pytest.mark.parametrize(
    ("joints", "message"),
    [
        (lambda: [DHJoint(a=0.0, alpha=0.0, d=0.0), DHJoint(a=0.5, alpha=0.0, d=0.0)], "6 joints"),
        (lambda: list(puma().description.joints)[:5], "6 joints"),
        (lambda: _replace(1, alpha=math.radians(90)), "alpha"),
        (lambda: _replace(3, alpha=0.0), "alpha"),
        (lambda: _replace(4, a=0.05), "a of joint 5"),
        (lambda: _replace(1, a=0.05), "a of joint 2"),
        (lambda: _replace(4, d=0.05), "d of joint 5"),
        (lambda: _replace(2, a=0.0), "a2"),
        (lambda: _replace(3, a=0.0, d=0.0), "forearm"),
    ],
)
def test_non_puma_tables_are_rejected(joints, message: str) -> None:
    with pytest.raises(InputError, match=message):
        puma_ik_all(joints(), np.eye(4))


def test_bad_pose_is_rejected() -> None:
    joints = puma().description.joints
    with pytest.raises(InputError, match="4, 4"):
        puma_ik_all(joints, np.eye(3))
    bad = np.eye(4)
    bad[0, 3] = np.nan
    with pytest.raises(InputError, match="finite"):
        puma_ik_all(joints, bad)
