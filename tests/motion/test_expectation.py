"""``shared.motion.expectation``: the reported arm's offset from the expected one, and the tool
point's path along a plan. Forward kinematics is computed here with pinocchio directly, then the
cell's frames written out: world_T_base (the pedestal, 660 mm up) and the tool point 110 mm
along the flange's z axis (peg_in_hole.toml)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tcp_oracle import WORLD_T_BASE, checked_frames, tcp_point  # noqa: F401

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_program
from shared.motion.expectation import ArmOffset, arm_offset, tool_path
from shared.motion.interpreter import plan_program
from shared.robots.jog import JogFrames


@pytest.fixture(scope="module")
def cell():
    return load_cell(DEFAULT_CELL)


@pytest.fixture(scope="module")
def frames(cell) -> JogFrames:
    return checked_frames(cell)




def test_the_same_arm_has_no_offset(cell, frames) -> None:
    off = arm_offset(cell.robot, frames, cell.q_home, cell.q_home.copy())
    assert off == ArmOffset(0.0, 0.0)
    assert not off.beyond(1e-9, 1e-9)


def test_the_offset_is_the_largest_joint_difference_and_the_tool_distance(cell, frames) -> None:
    expected = cell.q_home
    reported = expected + np.radians([0.5, -2.0, 1.0, 0.0, 0.25, -1.5])
    off = arm_offset(cell.robot, frames, reported, expected)
    assert off.joint == pytest.approx(math.radians(2.0), abs=1e-12)
    assert off.tool == pytest.approx(float(np.linalg.norm(tcp_point(cell, reported) - tcp_point(cell, expected))), abs=1e-12)
    assert off.tool > 0.001
    assert off.beyond(math.radians(1.0), 1.0) and off.beyond(math.radians(5.0), 0.001)
    assert not off.beyond(math.radians(5.0), 1.0)


def test_a_wrist_turn_about_the_tool_axis_moves_no_tool_point(cell, frames) -> None:
    # the tool point lies on joint 6's axis: turning it alone leaves the point where it is
    reported = cell.q_home.copy()
    reported[5] += math.radians(30.0)
    off = arm_offset(cell.robot, frames, reported, cell.q_home)
    assert off.joint == pytest.approx(math.radians(30.0), abs=1e-12)
    assert off.tool == pytest.approx(0.0, abs=1e-9)


def test_joint_vectors_of_different_sizes_are_infinitely_far(cell, frames) -> None:
    off = arm_offset(cell.robot, frames, cell.q_home[:3], cell.q_home)
    assert off.joint == math.inf and off.tool == math.inf
    assert off.beyond(1e9, 1e9)


def test_the_tool_path_runs_from_the_plans_start_to_its_end(cell, frames) -> None:
    statements = parse_program("DRIVE J1 TO 10 deg\nDRAW TO (600, 50, -300) mm IN BASE", "t.tp").statements
    plan = plan_program(statements, cell.robot, cell, start_q=cell.q_home)
    assert plan.refusal is None and plan.duration > 0
    path = tool_path(plan, cell.robot, frames, 25)
    assert path.shape == (25, 3)
    np.testing.assert_allclose(path[0], tcp_point(cell, plan.q_start), atol=1e-9)
    np.testing.assert_allclose(path[-1], tcp_point(cell, plan.q_final), atol=1e-9)
    # the DRAW ends where it was told: (600, 50, -300) mm in the base frame
    np.testing.assert_allclose(path[-1], (WORLD_T_BASE @ [0.6, 0.05, -0.3, 1.0])[:3], atol=1e-6)
    # evenly spaced in time: the middle point is the tool at half the plan's duration
    mid = plan.sample(plan.duration / 2).q[0]
    np.testing.assert_allclose(path[12], tcp_point(cell, mid), atol=1e-9)


def test_a_plan_that_takes_no_time_is_one_point(cell, frames) -> None:
    plan = plan_program(parse_program("SPEED 50 %", "t.tp").statements, cell.robot, cell, start_q=cell.q_home)
    assert plan.duration == 0.0
    path = tool_path(plan, cell.robot, frames, 10)
    assert path.shape == (1, 3)
    np.testing.assert_allclose(path[0], tcp_point(cell, cell.q_home), atol=1e-9)
    assert tool_path(plan_program([], cell.robot, cell, start_q=cell.q_home), cell.robot, frames, 5).shape == (1, 3)
