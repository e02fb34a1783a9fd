"""The planner routes MOVE and DRIVE round mechanical interference zones (seed 001): a straight
joint path that crosses a zone is detoured through its vertices, a goal inside one is refused."""

from __future__ import annotations

import numpy as np
import pytest

from shared.collision.interference import InterferenceZones, PolygonZone, points_in_polygon
from shared.language.statements import Drive, Move
from shared.motion import Interpreter, PlanRefused, RefusalReason
from shared.robots.loader import load_robot

ROBOT = load_robot("puma562")
# a square in the (J2, J3) plane, from -10 to +10 deg in J2 and 150 to 170 deg in J3
SQUARE = np.radians([[-10.0, 150.0], [10.0, 150.0], [10.0, 170.0], [-10.0, 170.0]])
ZONES = InterferenceZones.for_robot(ROBOT, [PolygonZone((2, 3), SQUARE, name="test square")])
START = np.radians([0.0, -30.0, 160.0, 0.0, 30.0, 0.0])


def interpreter(zones: InterferenceZones | None = ZONES) -> Interpreter:
    return Interpreter(ROBOT, START, zones=zones)


def test_a_crossing_move_is_detoured_and_never_enters_the_zone() -> None:
    goal = START.copy()
    goal[1] = np.radians(30.0)  # straight through the square at J3 = 160 deg
    segment = interpreter().plan_next(Move(joints=tuple(goal)))
    assert any("test square" in w for w in segment.warnings)
    samples = segment.sample(np.linspace(0.0, segment.duration, 2001))
    inside = points_in_polygon(samples.q[:, 1:3], SQUARE)  # the boundary itself is allowed (seed 001)
    assert not inside.any()
    np.testing.assert_allclose(samples.q[-1], goal, atol=1e-12)
    np.testing.assert_allclose(samples.q[0], START, atol=1e-12)
    # the velocity is continuous: no step between consecutive samples beyond what acceleration allows
    dt = samples.t[1] - samples.t[0]
    assert np.max(np.abs(np.diff(samples.qd, axis=0))) < 1.1 * np.max(interpreter().limits.joint_acceleration) * dt + 1e-9
    # without zones the same move goes straight through, and is shorter
    straight = interpreter(None).plan_next(Move(joints=tuple(goal)))
    assert straight.duration < segment.duration
    assert points_in_polygon(straight.sample(np.linspace(0, straight.duration, 201)).q[:, 1:3], SQUARE).any()


def test_a_goal_inside_a_zone_is_refused_with_the_reason() -> None:
    interp = interpreter()
    with pytest.raises(PlanRefused) as info:
        interp.plan_next(Drive(joint=2, target=float(np.radians(0.0))))
    assert info.value.reason is RefusalReason.INTERFERENCE
    assert "test square" in str(info.value)
    np.testing.assert_array_equal(interp.state.q, START)  # a refusal leaves the state unchanged


def test_a_move_beside_the_zone_is_straight() -> None:
    goal = START.copy()
    goal[2] = np.radians(120.0)  # J2 stays at -30 deg, left of the square
    segment = interpreter().plan_next(Move(joints=tuple(goal)))
    assert not any("interference" in w for w in segment.warnings)
    straight = interpreter(None).plan_next(Move(joints=tuple(goal)))
    assert segment.duration == pytest.approx(straight.duration)
