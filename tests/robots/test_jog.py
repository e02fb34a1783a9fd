"""Jogging follows thesis 4.3.4: joints turn about their own z; the tool keeps its constraint;
limits and singularities stop the motion with a reason instead of jumping."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.errors import InputError, UnknownNameError
from shared.robots.ik_puma import puma_ik_all  # noqa: F401 - the solver jog_tool_to uses (via shared.robots.ik): broken, it fails here
from shared.robots.jog import JogFrames, jog_joint, jog_tool, jog_tool_to, world_T_tcp
from shared.spatial import exp_so3, log_so3, pose_to_transform

CELL = load_cell(DEFAULT_CELL)
ROBOT = CELL.robot
FRAMES = JogFrames(CELL.world_T_base, CELL.frame("work"), CELL.flange_T_tcp)
AXES = {"x": [1, 0, 0], "y": [0, 1, 0], "z": [0, 0, 1], "xy": [1, 1, 0], "yz": [0, 1, 1], "xz": [1, 0, 1]}


def test_joint_turns_only_that_joint() -> None:
    result = jog_joint(ROBOT, CELL.q_home, 3, np.radians(5))
    assert result.moved and result.blocked is None
    change = result.q - CELL.q_home
    assert change[2] == pytest.approx(np.radians(5))
    assert np.count_nonzero(change) == 1


def test_joint_turns_about_its_own_z_axis() -> None:
    """The joint frame's z axis and origin stay put when that joint turns."""
    before = ROBOT.link_poses(CELL.q_home)
    after = ROBOT.link_poses(jog_joint(ROBOT, CELL.q_home, 2, np.radians(7)).q)
    np.testing.assert_allclose(before[2][:3, 2], after[2][:3, 2], atol=1e-12)
    np.testing.assert_allclose(before[2][:3, 3], after[2][:3, 3], atol=1e-12)


def test_joint_stops_at_its_limit_with_a_reason() -> None:
    q = CELL.q_home.copy()
    result = jog_joint(ROBOT, q, 5, np.radians(500))
    assert result.blocked == "joint_limit"
    assert result.q[4] == pytest.approx(ROBOT.upper[4])
    assert "J5" in result.message


def test_unknown_joint_and_names_are_errors() -> None:
    with pytest.raises(InputError, match="J7"):
        jog_joint(ROBOT, CELL.q_home, 7, 0.1)
    with pytest.raises(UnknownNameError, match="valid"):
        jog_tool(ROBOT, CELL.q_home, frames=FRAMES, frame="moon", constraint="x", motion="translate", displacement=np.ones(3))
    with pytest.raises(UnknownNameError):
        jog_tool(ROBOT, CELL.q_home, frames=FRAMES, frame="world", constraint="w", motion="translate", displacement=np.ones(3))


@settings(max_examples=60, deadline=None)
@given(
    frame=st.sampled_from(["world", "base", "work", "tool"]),
    constraint=st.sampled_from(list(AXES)),
    d=st.lists(st.floats(-0.01, 0.01), min_size=3, max_size=3),
)
def test_tool_translation_keeps_the_constraint(frame: str, constraint: str, d: list[float]) -> None:
    start = world_T_tcp(ROBOT, CELL.q_home, FRAMES)
    result = jog_tool(ROBOT, CELL.q_home, frames=FRAMES, frame=frame, constraint=constraint, motion="translate", displacement=np.array(d))
    assume(result.moved)
    end = world_T_tcp(ROBOT, result.q, FRAMES)
    rot = {"world": np.eye(3), "base": FRAMES.world_T_base[:3, :3], "work": FRAMES.world_T_work[:3, :3], "tool": start[:3, :3]}[frame]
    moved_in_frame = rot.T @ (end[:3, 3] - start[:3, 3])
    mask = np.array(AXES[constraint], dtype=float)
    np.testing.assert_allclose(moved_in_frame * (1 - mask), 0.0, atol=1e-9)  # nothing off the axis/plane
    np.testing.assert_allclose(moved_in_frame, mask * np.array(d), atol=1e-9)
    np.testing.assert_allclose(end[:3, :3], start[:3, :3], atol=1e-9)  # translation keeps orientation


@settings(max_examples=40, deadline=None)
@given(frame=st.sampled_from(["world", "tool"]), axis=st.sampled_from(["x", "y", "z"]), angle=st.floats(-0.05, 0.05))
def test_tool_rotation_keeps_the_point_and_axis(frame: str, axis: str, angle: float) -> None:
    start = world_T_tcp(ROBOT, CELL.q_home, FRAMES)
    d = np.zeros(3)
    d["xyz".index(axis)] = angle
    result = jog_tool(ROBOT, CELL.q_home, frames=FRAMES, frame=frame, constraint=axis, motion="rotate", displacement=d)
    assume(result.moved)
    end = world_T_tcp(ROBOT, result.q, FRAMES)
    np.testing.assert_allclose(end[:3, 3], start[:3, 3], atol=1e-9)  # rotation about the tool point
    rotvec_world = log_so3(end[:3, :3] @ start[:3, :3].T)
    frame_axis = (np.eye(3) if frame == "world" else start[:3, :3])[:, "xyz".index(axis)]
    np.testing.assert_allclose(rotvec_world, frame_axis * angle, atol=1e-9)


def test_gizmo_goal_is_projected_on_the_constraint() -> None:
    start = world_T_tcp(ROBOT, CELL.q_home, FRAMES)
    goal = start.copy()
    goal[:3, 3] += [0.02, 0.03, 0.05]
    goal[:3, :3] = exp_so3([0.0, 0.0, 0.3]) @ goal[:3, :3]
    result = jog_tool_to(ROBOT, CELL.q_home, goal, frames=FRAMES, frame="world", constraint="z", motion="translate")
    end = world_T_tcp(ROBOT, result.q, FRAMES)
    np.testing.assert_allclose(end[:3, 3] - start[:3, 3], [0.0, 0.0, 0.05], atol=1e-9)
    np.testing.assert_allclose(end[:3, :3], start[:3, :3], atol=1e-9)


def test_out_of_reach_is_blocked_not_jumped() -> None:
    result = jog_tool(ROBOT, CELL.q_home, frames=FRAMES, frame="world", constraint="x", motion="translate", displacement=np.array([3.0, 0, 0]))
    assert not result.moved
    assert result.blocked in ("unreachable", "joint_limit")
    np.testing.assert_array_equal(result.q, CELL.q_home)


def test_singularity_stops_instead_of_jumping() -> None:
    """Drive the wrist through q5 = 0 in small steps: the arm either moves smoothly or stops
    with the singularity reason, never a joint jump over the step limit."""
    q = np.radians([0.0, -45.0, 180.0, 30.0, 3.0, 0.0])
    frames = JogFrames.identity()
    saw_block = False
    for _ in range(40):
        result = jog_tool(ROBOT, q, frames=frames, frame="tool", constraint="y", motion="rotate", displacement=np.array([0.0, -0.01, 0.0]))
        if result.blocked:
            assert result.blocked == "singularity"
            saw_block = True
            break
        assert np.max(np.abs(result.q - q)) <= np.radians(20.0) + 1e-12
        q = result.q
    assert saw_block
