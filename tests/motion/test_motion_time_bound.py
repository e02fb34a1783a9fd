"""No motion is planned longer than a working day (``bounds.MAX_MOTION_S``), and the slowest speeds
the language allows plan finite motions within it: a planner never divides by a speed of zero."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language import bounds
from shared.language.parser import parse_statement
from shared.motion.interpreter import plan_program
from shared.motion.limits import MotionLimits
from shared.motion.refusal import RefusalReason

CELL = load_cell(DEFAULT_CELL)
ROBOT = CELL.robot


def _deg(values) -> str:
    return ", ".join(f"{v:.3f}" for v in np.degrees(values))


@pytest.mark.parametrize("speed", ["0.1 deg/s", "0.1 %"])
def test_the_slowest_joint_speeds_plan_the_longest_joint_move_within_the_bound(speed: str) -> None:
    lower, upper = ROBOT.lower + 1e-3, ROBOT.upper - 1e-3
    plan = plan_program([parse_statement(f"MOVE ({_deg(upper)}) deg WITH SPEED {speed}")], ROBOT, CELL, start_q=lower)
    assert plan.refusal is None, plan.refusal
    duration = plan.segments[0].duration
    assert math.isfinite(duration) and 0 < duration <= bounds.MAX_MOTION_S


def test_the_slowest_line_speed_plans_a_line_across_the_reach_within_the_bound() -> None:
    plan = plan_program([parse_statement("DRAW TO (400, -300, 250) mm WITH SPEED 0.1 mm/s"),
                         parse_statement("DRAW TO (400, 300, 250) mm WITH SPEED 0.1 mm/s")], ROBOT, CELL)
    assert plan.refusal is None, plan.refusal
    assert all(math.isfinite(s.duration) and s.duration <= bounds.MAX_MOTION_S for s in plan.segments)
    assert plan.segments[1].duration == pytest.approx(0.6 / 1e-4, rel=0.01)


def test_a_motion_planned_longer_than_a_working_day_is_refused_with_the_bound_named() -> None:
    """A robot far slower than any here: 0.1 % of 0.01 rad/s turns 90 deg in about 44 h."""
    slow = MotionLimits(joint_velocity=np.full(ROBOT.dof, 0.01), joint_acceleration=np.full(ROBOT.dof, 0.02))
    plan = plan_program([parse_statement("SPEED 0.1 %"), parse_statement("DRIVE J1 TO 90 deg")], ROBOT, CELL, limits=slow)
    assert plan.refusal is not None and plan.refusal.reason is RefusalReason.INVALID and plan.refusal.index == 1
    assert "longer than the 8 h bound on one motion" in str(plan.refusal)
    stopped = plan_program([parse_statement("SPEED 0.1 %"), parse_statement("DRIVE J1 TO 90 deg UNTIL TIME 60 s")],
                           ROBOT, CELL, limits=slow)
    assert stopped.refusal is None  # cut short by UNTIL TIME: it ends within the bound
