"""``shared.motion.back_away``: the tool point backs out of a contact along the way the failed
statement pressed, or straight up, by exactly the distance asked, in the world frame.

The oracles: straight-line directions computed here from the DRAW targets, and the tool point
from pinocchio's forward kinematics with the cell's frames written out (peg_in_hole.toml)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tcp_oracle import WORLD_T_BASE, checked_frames, tcp_point  # noqa: F401

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_statement
from shared.language.statements import Draw, Frame, SpeedUnit
from shared.motion.back_away import approach_direction, back_away_motion
from shared.motion.interpreter import plan_program
from shared.robots.jog import JogFrames

DISTANCE, SPEED = 0.03, 0.01
# found by sampling the joint ranges: the arm reaches up and out at the edge of its workspace,
# so no line from here plans (up is out of reach)
Q_AT_REACH = np.radians([34.1, -22.6, 101.8, 151.8, 63.2, -264.5])
# found by sampling: from here a line outward (away from the pedestal) leaves the reach, up does not
Q_OUT_IS_BLOCKED = np.radians([115.6, -21.9, 117.5, -29.5, 56.6, -132.3])


@pytest.fixture(scope="module")
def cell():
    return load_cell(DEFAULT_CELL)


@pytest.fixture(scope="module")
def frames(cell) -> JogFrames:
    return checked_frames(cell)




def end_of(cell, motion, q) -> np.ndarray:
    """Where the tool point ends when ``motion`` is planned from ``q``."""
    plan = plan_program([motion], cell.robot, cell, start_q=q)
    assert plan.refusal is None
    return tcp_point(cell, plan.q_final)


def test_the_approach_of_a_draw_is_its_lines_direction(cell, frames) -> None:
    failed = parse_statement("DRAW TO (600, 50, -300) mm IN BASE")
    start = tcp_point(cell, cell.q_home)
    target = (WORLD_T_BASE @ [0.6, 0.05, -0.3, 1.0])[:3]
    line = (target - start) / np.linalg.norm(target - start)
    got = approach_direction(failed, cell.robot, cell, frames, cell.q_home)
    assert got is not None and np.linalg.norm(got) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(got, line, atol=1e-3)


def test_backing_away_from_a_draw_goes_the_distance_against_its_approach(cell, frames) -> None:
    q = cell.q_home
    failed = parse_statement("DRAW TO (600, 50, -300) mm IN BASE")
    start = tcp_point(cell, q)
    target = (WORLD_T_BASE @ [0.6, 0.05, -0.3, 1.0])[:3]
    line = (target - start) / np.linalg.norm(target - start)
    answer = back_away_motion(cell.robot, cell, frames, q, failed, distance=DISTANCE, speed=SPEED)
    motion = answer.motion
    assert motion is not None and answer.refusal == ""
    assert isinstance(motion, Draw) and motion.frame is Frame.WORLD
    assert motion.speed.unit is SpeedUnit.M_PER_S and motion.speed.value == SPEED
    step = np.array(motion.position) - start
    assert np.linalg.norm(step) == pytest.approx(DISTANCE, abs=1e-12)
    np.testing.assert_allclose(step, -DISTANCE * line, atol=DISTANCE * 1e-3)
    # planned, the tool point goes there
    np.testing.assert_allclose(end_of(cell, motion, q), motion.position, atol=1e-6)


def test_without_a_failed_statement_the_tool_backs_straight_up(cell, frames) -> None:
    q = cell.q_home
    start = tcp_point(cell, q)
    motion = back_away_motion(cell.robot, cell, frames, q, None, distance=DISTANCE, speed=SPEED).motion
    assert motion is not None and motion.frame is Frame.WORLD
    np.testing.assert_allclose(motion.position, start + [0.0, 0.0, DISTANCE], atol=1e-12)
    np.testing.assert_allclose(end_of(cell, motion, q), start + [0.0, 0.0, DISTANCE], atol=1e-6)


@pytest.mark.parametrize("text", [
    "DRIVE J6 TO 100 deg",  # the tool point lies on joint 6's axis: turning it moves no point
    "DRIVE J2 TO 60 deg",  # past J2's range: cannot be planned
    "SPEED 20 %",  # takes no time
])
def test_a_failed_statement_without_an_approach_backs_up(cell, frames, text) -> None:
    failed = parse_statement(text)
    assert approach_direction(failed, cell.robot, cell, frames, cell.q_home) is None
    start = tcp_point(cell, cell.q_home)
    motion = back_away_motion(cell.robot, cell, frames, cell.q_home, failed, distance=DISTANCE, speed=SPEED).motion
    np.testing.assert_allclose(motion.position, start + [0.0, 0.0, DISTANCE], atol=1e-12)


def test_when_the_way_back_cannot_be_planned_the_tool_backs_up(cell, frames) -> None:
    q = Q_OUT_IS_BLOCKED
    start = tcp_point(cell, q)
    outward = np.array([start[0], start[1], 0.0]) / math.hypot(start[0], start[1])
    failed = Draw(position=tuple(start - 0.05 * outward), frame=Frame.WORLD)  # pressing inward
    approach = approach_direction(failed, cell.robot, cell, frames, q)
    assert approach is not None
    np.testing.assert_allclose(approach, -outward, atol=1e-2)
    motion = back_away_motion(cell.robot, cell, frames, q, failed, distance=DISTANCE, speed=SPEED).motion
    assert motion is not None
    np.testing.assert_allclose(motion.position, start + [0.0, 0.0, DISTANCE], atol=1e-12)


def test_nothing_plannable_is_a_refusal_saying_why(cell, frames) -> None:
    q = Q_AT_REACH
    answer = back_away_motion(cell.robot, cell, frames, q, None, distance=DISTANCE, speed=SPEED)
    assert answer.motion is None
    assert "reach" in answer.refusal
    pressing_down = Draw(position=tuple(tcp_point(cell, q) - [0.0, 0.0, 0.05]), frame=Frame.WORLD)
    answer = back_away_motion(cell.robot, cell, frames, q, pressing_down, distance=DISTANCE, speed=SPEED)
    assert answer.motion is None and answer.refusal
