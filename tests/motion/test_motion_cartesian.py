"""DRAW, ROTATE, MOVES: straight tool lines with slerped orientation, in every frame."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.language.statements import Draw, Moves, Rotate, SetSpeed, Speed
from shared.motion import PUMA_LIMITS, Interpreter, PlanRefused, RefusalReason
from shared.robots.loader import load_robot
from shared.spatial import exp_so3, log_so3, rpy_to_matrix

DOWN = (math.pi, 0.0, 0.0)  # tool z pointing down


def tool_poses(interp: Interpreter, seg, n: int = 801) -> np.ndarray:
    ts = np.linspace(0.0, seg.duration, n)
    return np.stack([interp.frames.world_T_tcp(interp.robot, q) for q in seg.sample(ts).q])


def line_deviation(poses: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> float:
    d = p1 - p0
    u = d / np.linalg.norm(d)
    r = poses[:, :3, 3] - p0
    along = r @ u
    assert np.all(along >= -1e-7) and np.all(along <= np.linalg.norm(d) + 1e-7)  # never overshoots the ends
    return float(np.max(np.linalg.norm(r - np.outer(along, u), axis=1)))


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(log_so3(a.T @ b)))


def test_draw_in_work_stays_on_the_line_and_keeps_its_orientation(cell) -> None:
    interp = Interpreter.for_cell(cell)
    start = interp.state.world_T_tcp.copy()
    seg = interp.plan_next(Draw(position=(0.05, -0.08, 0.15), frame="WORK"))
    poses = tool_poses(interp, seg)
    goal = cell.frame("work")[:3, :3] @ np.array([0.05, -0.08, 0.15]) + cell.frame("work")[:3, 3]
    assert line_deviation(poses, start[:3, 3], goal) < 1e-4
    assert np.linalg.norm(poses[-1, :3, 3] - goal) < 1e-6
    assert max(angle_between(start[:3, :3], p[:3, :3]) for p in poses) < 1e-3
    np.testing.assert_allclose(interp.state.world_T_tcp[:3, 3], goal, atol=1e-6)


def test_moves_slerps_the_orientation_in_step_with_the_position(cell) -> None:
    interp = Interpreter.for_cell(cell)
    start = interp.state.world_T_tcp.copy()
    rpy = (math.pi, math.radians(15.0), math.radians(40.0))
    seg = interp.plan_next(Moves(position=(-0.05, 0.1, 0.12), rpy=rpy, frame="WORK"))
    poses = tool_poses(interp, seg)
    world_T_work = cell.frame("work")
    goal_p = world_T_work[:3, :3] @ np.array([-0.05, 0.1, 0.12]) + world_T_work[:3, 3]
    goal_r = world_T_work[:3, :3] @ rpy_to_matrix(np.array(rpy))
    assert line_deviation(poses, start[:3, 3], goal_p) < 1e-4
    length = np.linalg.norm(goal_p - start[:3, 3])
    phi = log_so3(start[:3, :3].T @ goal_r)
    for pose in poses:
        fraction = np.linalg.norm(pose[:3, 3] - start[:3, 3]) / length
        assert angle_between(start[:3, :3] @ exp_so3(fraction * phi), pose[:3, :3]) < 1e-3
    assert angle_between(poses[-1][:3, :3], goal_r) < 1e-6


def test_rotate_turns_in_place(cell) -> None:
    interp = Interpreter.for_cell(cell)
    start = interp.state.world_T_tcp.copy()
    rpy = (math.pi, 0.0, math.radians(-60.0))
    seg = interp.plan_next(Rotate(rpy=rpy, frame="WORLD"))
    poses = tool_poses(interp, seg)
    assert np.max(np.linalg.norm(poses[:, :3, 3] - start[:3, 3], axis=1)) < 1e-4
    assert angle_between(poses[-1][:3, :3], rpy_to_matrix(np.array(rpy))) < 1e-6
    angles = [angle_between(start[:3, :3], p[:3, :3]) for p in poses]
    assert np.all(np.diff(angles) >= -1e-6)  # turns one way, about one axis


def test_tool_frame_targets_are_relative_to_the_pose_at_the_statement_start(cell) -> None:
    interp = Interpreter.for_cell(cell)
    start = interp.state.world_T_tcp.copy()
    interp.plan_next(Draw(position=(0.0, 0.0, 0.05), frame="TOOL"))  # 50 mm along the tool's own z
    np.testing.assert_allclose(interp.state.world_T_tcp[:3, 3], start[:3, 3] + 0.05 * start[:3, 2], atol=1e-6)
    middle = interp.state.world_T_tcp.copy()
    interp.plan_next(Rotate(rpy=(0.0, 0.0, math.radians(30.0)), frame="TOOL"))
    expected = middle[:3, :3] @ rpy_to_matrix(np.array([0.0, 0.0, math.radians(30.0)]))
    assert angle_between(interp.state.world_T_tcp[:3, :3], expected) < 1e-6


def test_base_frame_targets_use_where_the_robot_stands(cell) -> None:
    interp = Interpreter.for_cell(cell)
    base_p = np.array([0.5, 0.05, -0.15])
    interp.plan_next(Draw(position=tuple(base_p), frame="BASE"))
    world_p = cell.world_T_base[:3, :3] @ base_p + cell.world_T_base[:3, 3]
    np.testing.assert_allclose(interp.state.world_T_tcp[:3, 3], world_p, atol=1e-6)
    assert not np.allclose(world_p, base_p)  # the frames differ in this cell, so the test means something


def test_cartesian_motion_keeps_joints_within_their_limits(cell) -> None:
    interp = Interpreter.for_cell(cell)
    interp.plan_next(SetSpeed(speed=Speed(value=1.0, unit="fraction")))
    seg = interp.plan_next(Moves(position=(0.1, 0.12, 0.25), rpy=(math.pi, math.radians(-20.0), math.radians(70.0)), frame="WORK"))
    dt = 1e-3
    ts = np.arange(0.0, seg.duration + dt, dt)
    q = seg.sample(ts).q
    v = np.max(np.abs(np.diff(q, axis=0)) / dt, axis=0)
    a = np.max(np.abs(np.diff(q, n=2, axis=0)) / dt**2, axis=0)
    assert np.all(v <= PUMA_LIMITS.joint_velocity * 1.01)
    assert np.all(a <= PUMA_LIMITS.joint_acceleration * 1.02)
    assert np.all(q >= cell.robot.lower - 1e-9) and np.all(q <= cell.robot.upper + 1e-9)


def test_with_speed_in_mm_per_s_sets_the_tool_speed_on_a_line(cell) -> None:
    interp = Interpreter.for_cell(cell)
    start = interp.state.world_T_tcp[:3, 3]
    goal = start + np.array([0.1, 0.0, 0.0])
    seg = interp.plan_next(Draw(position=tuple(goal), speed=Speed(value=0.02, unit="m/s")))
    # 100 mm at 20 mm/s: 5 s of cruise plus the ramps (the ramps may be gentler than the tool's
    # acceleration limit where a joint's acceleration binds)
    v_s, a_s = 0.02 / 0.1, PUMA_LIMITS.linear_acceleration / 0.1
    assert 1.0 / v_s + v_s / a_s - 1e-9 <= seg.duration < 1.0 / v_s + 0.05
    dt = 1e-3
    ts = np.arange(0.0, seg.duration + dt, dt)
    p = np.stack([interp.frames.world_T_tcp(interp.robot, q)[:3, 3] for q in seg.sample(ts).q])
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    assert 0.0199 < np.max(speed) < 0.0201


def test_speed_fraction_scales_a_line(cell) -> None:
    durations = []
    for fraction in (1.0, 0.2):
        interp = Interpreter.for_cell(cell)
        interp.plan_next(SetSpeed(speed=Speed(value=fraction, unit="fraction")))
        durations.append(interp.plan_next(Draw(position=(0.0, 0.0, 0.4), frame="WORK")).duration)
    assert durations[1] > 2.0 * durations[0]


def test_a_target_out_of_reach_is_refused_with_where(cell) -> None:
    interp = Interpreter.for_cell(cell)
    with pytest.raises(PlanRefused) as info:
        interp.plan_next(Draw(position=(1.5, 0.0, 0.9)))
    assert info.value.reason is RefusalReason.UNREACHABLE
    assert 0.0 < info.value.at <= 1.0
    assert "mm in WORLD" in str(info.value)


def test_a_line_that_takes_a_joint_past_its_limit_is_refused_naming_the_joint() -> None:
    robot = load_robot("puma562")
    interp = Interpreter(robot, np.radians([0.0, -45.0, 180.0, 0.0, 45.0, 0.0]))
    with pytest.raises(PlanRefused) as info:
        interp.plan_next(Rotate(rpy=(math.radians(120.0), 0.0, 0.0), frame="TOOL"))
    assert info.value.reason is RefusalReason.JOINT_LIMIT
    assert "joint 5" in str(info.value) and "100.0 deg" in str(info.value)


def test_speed_units_that_do_not_fit_the_motion_are_refused(cell) -> None:
    interp = Interpreter.for_cell(cell)
    with pytest.raises(PlanRefused) as info:
        interp.plan_next(Draw(position=(0.0, 0.0, 0.1), frame="WORK", speed=Speed(value=0.5, unit="rad/s")))
    assert info.value.reason is RefusalReason.INVALID and "DRAW cannot take WITH SPEED in deg/s" in str(info.value)
    with pytest.raises(PlanRefused) as info:
        interp.plan_next(Rotate(rpy=DOWN, speed=Speed(value=0.05, unit="m/s")))
    assert info.value.reason is RefusalReason.INVALID and "ROTATE cannot take WITH SPEED in mm/s" in str(info.value)


def test_planning_is_deterministic(cell) -> None:
    program = [
        Moves(position=(0.05, 0.05, 0.1), rpy=(math.pi, 0.0, 0.3), frame="WORK"),
        Draw(position=(0.0, 0.0, -0.05), frame="TOOL"),
    ]
    runs = []
    for _ in range(2):
        interp = Interpreter.for_cell(cell)
        segs = [interp.plan_next(s) for s in program]
        runs.append(np.concatenate([s.sample(np.linspace(0, s.duration, 97)).q for s in segs]))
    np.testing.assert_array_equal(runs[0], runs[1])


coords = st.floats(min_value=-0.25, max_value=0.25, allow_nan=False)
angles = st.floats(min_value=-math.pi / 3, max_value=math.pi / 3, allow_nan=False)


@settings(max_examples=25, deadline=None)
@given(x=coords, y=coords, z=st.floats(min_value=0.05, max_value=0.35), yaw=angles, pitch=angles)
def test_any_moves_is_either_on_its_line_within_limits_or_refused_with_a_reason(cell, x, y, z, yaw, pitch) -> None:
    interp = Interpreter.for_cell(cell)
    start = interp.state.world_T_tcp.copy()
    try:
        seg = interp.plan_next(Moves(position=(x, y, z), rpy=(math.pi, pitch, yaw), frame="WORK"))
    except PlanRefused as exc:
        assert exc.reason in (RefusalReason.UNREACHABLE, RefusalReason.JOINT_LIMIT, RefusalReason.JOINT_JUMP)
        assert exc.at is not None and 0.0 <= exc.at <= 1.0
        return
    poses = tool_poses(interp, seg, n=201)
    goal = interp.state.world_T_tcp[:3, 3]
    if np.linalg.norm(goal - start[:3, 3]) > 1e-6:
        assert line_deviation(poses, start[:3, 3], goal) < 1e-4
    q = seg.sample(np.linspace(0.0, seg.duration, 201))
    assert np.all(q.q >= cell.robot.lower - 1e-9) and np.all(q.q <= cell.robot.upper + 1e-9)
    assert np.all(np.abs(q.qd) <= PUMA_LIMITS.joint_velocity * 0.5 * (1 + 1e-9))  # default speed 50 %
    assert np.all(np.abs(q.qdd) <= PUMA_LIMITS.joint_acceleration * (1 + 1e-9))


def test_with_speed_in_deg_per_s_sets_the_tool_rotation_rate(cell) -> None:
    interp = Interpreter.for_cell(cell)
    rate = math.radians(10.0)
    seg = interp.plan_next(Rotate(rpy=(math.pi, 0.0, math.radians(40.0)), frame="WORK", speed=Speed(value=rate, unit="rad/s")))
    dt = 1e-2
    ts = np.arange(0.0, seg.duration + dt, dt)
    rotations = [interp.frames.world_T_tcp(interp.robot, q)[:3, :3] for q in seg.sample(ts).q]
    speeds = np.array([angle_between(a, b) for a, b in zip(rotations[:-1], rotations[1:])]) / dt
    assert rate * 0.99 < np.max(speeds) <= rate * 1.001


def test_a_target_beyond_a_joint_range_is_refused_naming_the_joint() -> None:
    robot = load_robot("puma562")
    interp = Interpreter(robot, np.radians([0.0, -45.0, 180.0, 0.0, 45.0, 0.0]))
    with pytest.raises(PlanRefused) as info:  # tilting the tool 60 deg more needs q5 = 105 deg
        interp.plan_next(Rotate(rpy=(0.0, math.radians(60.0), 0.0), frame="TOOL"))
    assert info.value.reason is RefusalReason.JOINT_LIMIT
    assert "needs joint 5 beyond its limit of 100.0 deg" in str(info.value) and info.value.at == 1.0
