"""The compiled nearest-solution IK (``solve_ik_nearest``) returns exactly ``solve_ik``'s first
solution, and None exactly where ``solve_ik`` has none: on random reachable poses and random
seeds, at the wrist singularity, with offsets, reversed joints, frames and ranges wider than a
turn, with a limit tolerance, and through the fallback for robots without the PUMA closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.errors import InputError
from shared.robots.description import DHJoint, RobotDescription
from shared.robots.ik import solve_ik
from shared.robots.ik_kernels import solve_ik_nearest
from shared.robots.loader import load_robot
from shared.robots.model import Robot, build_dh_model
from shared.spatial import exp_so3

Q_TOL = 1e-9  # rad: the same solution, to rounding
POSE_TOL = 1e-9


def make_robot(joints: list[DHJoint], **fields: object) -> Robot:
    desc = RobotDescription(
        name="custom", source="test", convention="modified", joints=tuple(joints),
        flange_T_tool=fields.pop("flange_T_tool", np.eye(4)), ik="puma", **fields,  # type: ignore[arg-type]
    )
    model, tool_id, link_ids = build_dh_model(desc)
    return Robot(desc, model, tool_id, link_ids)


def pose(rotvec: list[float], p: list[float]) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = exp_so3(np.array(rotvec))
    out[:3, 3] = p
    return out


def general_robot() -> Robot:
    """Table 4.1's structure with offsets, reversed joints, non-zero d1, d3, d6, a placed base and
    tool, ranges wider than a turn (several 2 pi variants of a solution) and a limit tolerance."""
    deg = math.radians
    joints = [
        DHJoint(a=0.0, alpha=0.0, d=0.3, offset=deg(30), sign=-1, lower=deg(-170), upper=deg(170)),
        DHJoint(a=0.0, alpha=deg(-90), d=0.1, offset=deg(-90), lower=deg(-200), upper=deg(40)),
        DHJoint(a=0.4, alpha=0.0, d=0.05, offset=deg(10), sign=-1, lower=deg(-60), upper=deg(230)),
        DHJoint(a=0.03, alpha=deg(90), d=0.38, offset=deg(180), lower=deg(-400), upper=deg(400)),
        DHJoint(a=0.0, alpha=deg(-90), d=0.0, offset=deg(5), sign=-1, lower=deg(-120), upper=deg(120)),
        DHJoint(a=0.0, alpha=deg(90), d=0.07, offset=deg(-45), lower=deg(-540), upper=deg(540)),
    ]
    return make_robot(
        joints,
        base_T_chain=pose([0.1, -0.2, 0.3], [0.2, -0.1, 0.05]),
        flange_T_tool=pose([0.0, 0.3, 0.0], [0.01, 0.0, 0.12]),
        ik_limit_tolerance=1e-3,
    )


def assert_same_as_solve_ik(robot: Robot, target: np.ndarray, seed: np.ndarray, **kwargs: object) -> np.ndarray | None:
    solutions = solve_ik(robot, target, q_near=seed, **kwargs)  # type: ignore[arg-type]
    got = solve_ik_nearest(robot, target, seed, **kwargs)  # type: ignore[arg-type]
    if not solutions:
        assert got is None
        return None
    assert got is not None
    np.testing.assert_allclose(got, solutions[0], rtol=0.0, atol=Q_TOL)
    return got


@pytest.mark.parametrize("respect_limits", [True, False])
def test_random_poses_and_seeds_match_solve_ik(respect_limits: bool) -> None:
    robot = load_robot("puma562")
    rng = np.random.default_rng(21)
    found = 0
    for _ in range(400):
        q = rng.uniform(robot.lower, robot.upper)
        target = robot.fk(q).copy()
        for seed in (rng.uniform(robot.lower, robot.upper), q + rng.normal(0.0, 0.02, 6)):
            got = assert_same_as_solve_ik(robot, target, seed, respect_limits=respect_limits)
            if got is not None:
                found += 1
                np.testing.assert_allclose(robot.fk(got), target, atol=POSE_TOL)
                if respect_limits:
                    assert robot.within_limits(got)
    assert found == 800  # every pose is FK of a q within the ranges: never None here


def test_a_close_seed_gives_back_the_original_joints() -> None:
    robot = load_robot("puma562")
    rng = np.random.default_rng(5)
    for _ in range(200):
        q = rng.uniform(robot.lower, robot.upper)
        q[4] = math.copysign(max(abs(q[4]), 0.05), q[4])  # away from the wrist singularity
        got = solve_ik_nearest(robot, robot.fk(q).copy(), q + rng.normal(0.0, 1e-3, 6))
        assert got is not None
        np.testing.assert_allclose(got, q, atol=1e-7)


def test_wrist_singular_poses_match_solve_ik() -> None:
    robot = load_robot("puma562")
    rng = np.random.default_rng(7)
    for _ in range(200):
        q = rng.uniform(robot.lower, robot.upper)
        q[4] = 0.0
        target = robot.fk(q).copy()
        seed = q + rng.normal(0.0, 0.05, 6)
        seed = np.clip(seed, robot.lower, robot.upper)
        got = assert_same_as_solve_ik(robot, target, seed)
        assert got is not None
        np.testing.assert_allclose(robot.fk(got), target, atol=POSE_TOL)
        # (nearest is solve_ik's squared joint distance: with q4 + q6 the only fixed part of the
        # wrist, another arm posture can be nearer; rounding decides whether sin q5 reads as zero)
        for_free = assert_same_as_solve_ik(robot, target, seed, respect_limits=False)
        assert for_free is not None


def test_general_robot_with_frames_variants_and_tolerance_matches() -> None:
    robot = general_robot()
    rng = np.random.default_rng(11)
    for k in range(300):
        q = rng.uniform(robot.lower, robot.upper)
        if k % 4 == 0:
            q[4] = 0.0
        target = robot.fk(q).copy()
        wide = rng.uniform(robot.lower - 1.0, robot.upper + 1.0)  # seeds outside the ranges too
        for seed in (wide, q + rng.normal(0.0, 0.01, 6)):
            assert_same_as_solve_ik(robot, target, seed)
            assert_same_as_solve_ik(robot, target, seed, respect_limits=False)
            assert_same_as_solve_ik(robot, target, seed, limit_tolerance=0.0)
            assert_same_as_solve_ik(robot, target, seed, limit_tolerance=0.05)


def test_a_target_just_past_a_limit_is_clamped_like_solve_ik() -> None:
    robot = general_robot()
    q = np.zeros(6)
    q[0] = robot.upper[0] + 5e-4  # inside the robot's 1e-3 tolerance band
    target = robot.fk(q).copy()
    got = assert_same_as_solve_ik(robot, target, q)
    assert got is not None and got[0] == robot.upper[0]
    assert_same_as_solve_ik(robot, target, q, limit_tolerance=0.0)  # then that branch is dropped, as there


def test_unreachable_and_out_of_range_targets_give_none() -> None:
    robot = load_robot("puma562")
    far = np.eye(4)
    far[:3, 3] = [5.0, 0.0, 0.0]
    assert solve_ik(robot, far) == []
    assert solve_ik_nearest(robot, far, np.zeros(6)) is None
    assert solve_ik_nearest(robot, far, np.zeros(6), respect_limits=False) is None
    rng = np.random.default_rng(3)
    nones = 0
    for _ in range(300):  # poses some of whose solutions (or all) need a joint past its range
        q = rng.uniform(-math.pi, math.pi, 6)
        target = robot.fk(q).copy()
        if assert_same_as_solve_ik(robot, target, rng.uniform(robot.lower, robot.upper)) is None:
            nones += 1
    assert nones > 0


def test_exactly_singular_wrist_takes_the_seed_q4() -> None:
    robot = load_robot("puma562")
    target = robot.fk(np.array([0.2, -0.7, 1.1, 0.0, 0.0, 0.0])).copy()
    target[:3, :3] = np.round(target[:3, :3], 12)  # keep it a rotation to rounding
    for q4 in (-1.0, 0.4, 2.5):
        seed = np.array([0.2, -0.7, 1.1, q4, 0.0, 0.3])
        got = assert_same_as_solve_ik(robot, target, seed)
        assert got is not None
        np.testing.assert_allclose(robot.fk(got), target, atol=1e-9)
        assert got[3] == pytest.approx(q4, abs=1e-12) and got[5] == pytest.approx(-q4, abs=1e-9)  # q4 kept, q6 takes the rest


def test_the_default_seed_is_zero() -> None:
    robot = load_robot("puma562")
    target = robot.fk(np.array([0.3, -0.4, 0.5, 0.2, 0.6, -0.1])).copy()
    np.testing.assert_allclose(solve_ik_nearest(robot, target), solve_ik(robot, target)[0], atol=Q_TOL)


def test_rover_uses_its_own_closed_form() -> None:
    robot = load_robot("rover")
    rng = np.random.default_rng(2)
    for _ in range(50):
        q = rng.uniform(robot.lower, robot.upper)
        p = robot.fk(q)[:3, 3].copy()
        seed = rng.uniform(robot.lower, robot.upper)
        solutions = solve_ik(robot, position=p, q_near=seed)
        got = solve_ik_nearest(robot, position=p, q_seed=seed)
        assert got is not None and solutions
        np.testing.assert_array_equal(got, solutions[0])


def test_bad_inputs_are_refused_as_by_solve_ik() -> None:
    robot = load_robot("puma562")
    target = robot.fk(np.zeros(6)).copy()
    with pytest.raises(InputError, match="full tool pose"):
        solve_ik_nearest(robot, position=target[:3, 3])
    with pytest.raises(InputError, match="NaN"):
        solve_ik_nearest(robot, target, np.full(6, np.nan))
    with pytest.raises(InputError, match="6 joints"):
        solve_ik_nearest(robot, target, np.zeros(5))
    bad = target.copy()
    bad[0, 3] = np.inf
    with pytest.raises(InputError, match="finite"):
        solve_ik_nearest(robot, bad, np.zeros(6))
    with pytest.raises(InputError, match="tolerance"):
        solve_ik_nearest(robot, target, np.zeros(6), limit_tolerance=-1.0)
    not_puma = load_robot("puma562").description.joints
    broken = list(not_puma)
    broken[2] = DHJoint(a=0.0, alpha=broken[2].alpha, d=broken[2].d)
    with pytest.raises(InputError, match="a2"):
        solve_ik_nearest(make_robot(broken), target, np.zeros(6))


@pytest.mark.parametrize("name, position_only", [("puma562", False), ("rover", True)])
def test_one_rule_says_what_a_robots_ik_takes(name: str, position_only: bool) -> None:
    """Jogging, path planning and program checks all hand the IK what ``ik_target`` gives: the
    whole tool pose, or only its position for an arm that places its tool point only."""
    from shared.robots.ik import ik_target, positions_tool_only

    robot = load_robot(name)
    q = np.clip(np.full(robot.dof, 0.3), robot.lower, robot.upper)
    base_T_tool = robot.fk(q)
    assert positions_tool_only(robot) is position_only
    target = ik_target(robot, base_T_tool)
    assert set(target) == ({"position"} if position_only else {"base_T_tool"})
    best = solve_ik_nearest(robot, q_seed=q, **target)
    assert best is not None
    np.testing.assert_allclose(robot.fk(best)[:3, 3], base_T_tool[:3, 3], atol=1e-6)
