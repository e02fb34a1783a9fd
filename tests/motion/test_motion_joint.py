"""MOVE and DRIVE: synchronised joint moves that reach their targets within the limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.errors import InputError
from shared.language.statements import Drive, Move, SetSpeed, Speed
from shared.motion import PUMA_LIMITS, Interpreter, MotionLimits, PlanRefused, RefusalReason
from shared.robots.loader import load_robot

ROBOT = load_robot("puma562")
Q0 = np.radians([0.0, -45.0, 180.0, 0.0, 45.0, 0.0])
TARGET = np.radians([40.0, -80.0, 150.0, 60.0, -30.0, 90.0])


def fraction(v: float) -> Speed:
    return Speed(value=v, unit="fraction")


def finite_difference_peaks(seg, dt: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """Largest |velocity| and |acceleration| per joint, from differences of sampled positions."""
    ts = np.arange(0.0, seg.duration + dt, dt)
    q = seg.sample(ts).q
    v = np.diff(q, axis=0) / dt
    a = np.diff(q, n=2, axis=0) / (dt * dt)
    return np.max(np.abs(v), axis=0), np.max(np.abs(a), axis=0)


def test_move_reaches_its_target_with_all_joints_arriving_together() -> None:
    seg = Interpreter(ROBOT, Q0).plan_next(Move(joints=tuple(TARGET)))
    assert seg.duration > 0
    np.testing.assert_array_equal(seg.sample(0.0).q[0], Q0)
    np.testing.assert_array_equal(seg.sample(seg.duration).q[0], TARGET)
    ts = np.linspace(0.0, seg.duration, 101)
    progress = (seg.sample(ts).q - Q0) / (TARGET - Q0)
    # every joint has covered the same fraction of its way at every instant
    assert np.max(np.ptp(progress, axis=1)) < 1e-12
    assert np.all(np.diff(progress[:, 0]) >= -1e-12)


@pytest.mark.parametrize("speed", [1.0, 0.5, 0.1])
def test_joint_velocity_and_acceleration_stay_within_limits(speed: float) -> None:
    interp = Interpreter(ROBOT, Q0)
    interp.plan_next(SetSpeed(speed=fraction(speed)))
    seg = interp.plan_next(Move(joints=tuple(TARGET)))
    v, a = finite_difference_peaks(seg)
    v_lim = PUMA_LIMITS.joint_velocity * speed
    assert np.all(v <= v_lim * (1 + 1e-6))
    assert np.all(a <= PUMA_LIMITS.joint_acceleration * (1 + 1e-6))
    # and the move is as fast as allowed: the binding joint reaches its limit
    assert np.max(v / v_lim) > 0.999
    # the analytic derivatives agree with the sampled ones
    samples = seg.sample(np.linspace(0, seg.duration, 1001))
    assert np.all(np.max(np.abs(samples.qd), axis=0) <= v_lim * (1 + 1e-9))


def expected_duration(delta: np.ndarray, speed: float, limits: MotionLimits = PUMA_LIMITS) -> float:
    moving = np.abs(delta) > 0
    v_s = np.min(limits.joint_velocity[moving] * speed / np.abs(delta[moving]))
    a_s = np.min(limits.joint_acceleration[moving] / np.abs(delta[moving]))
    if v_s * v_s / a_s < 1.0:
        return 1.0 / v_s + v_s / a_s
    return 2.0 / math.sqrt(a_s)


def test_speed_settings_change_durations_as_the_profile_says() -> None:
    durations = {}
    for speed in (1.0, 0.5, 0.25):
        interp = Interpreter(ROBOT, Q0)
        interp.plan_next(SetSpeed(speed=fraction(speed)))
        durations[speed] = interp.plan_next(Move(joints=tuple(TARGET))).duration
        assert math.isclose(durations[speed], expected_duration(TARGET - Q0, speed), rel_tol=1e-12)
    assert durations[1.0] < durations[0.5] < durations[0.25]
    # WITH SPEED replaces the SPEED setting for its one action
    interp = Interpreter(ROBOT, Q0)
    interp.plan_next(SetSpeed(speed=fraction(1.0)))
    with_speed = interp.plan_next(Move(joints=tuple(TARGET), speed=fraction(0.25))).duration
    assert math.isclose(with_speed, durations[0.25], rel_tol=1e-12)
    # ... and the setting is back for the next one
    back = interp.plan_next(Move(joints=tuple(Q0))).duration
    assert math.isclose(back, durations[1.0], rel_tol=1e-12)


def test_default_speed_is_half_of_the_maximum() -> None:
    seg = Interpreter(ROBOT, Q0).plan_next(Move(joints=tuple(TARGET)))
    assert math.isclose(seg.duration, expected_duration(TARGET - Q0, 0.5), rel_tol=1e-12)


def test_with_speed_in_deg_per_s_caps_every_joint() -> None:
    cap = math.radians(20.0)
    seg = Interpreter(ROBOT, Q0).plan_next(Move(joints=tuple(TARGET), speed=Speed(value=cap, unit="rad/s")))
    v, _ = finite_difference_peaks(seg)
    assert np.max(v) <= cap * (1 + 1e-6)
    assert np.max(v) > 0.999 * cap


def test_speed_units_a_joint_move_cannot_take_are_refused() -> None:
    interp = Interpreter(ROBOT, Q0)
    with pytest.raises(PlanRefused) as info:
        interp.plan_next(Move(joints=tuple(TARGET), speed=Speed(value=0.05, unit="m/s")))
    assert info.value.reason is RefusalReason.INVALID and "MOVE cannot take WITH SPEED in mm/s" in str(info.value)
    interp.plan_next(SetSpeed(speed=Speed(value=0.05, unit="m/s")))  # fine for the lines that follow ...
    with pytest.raises(PlanRefused) as info:  # ... but not for a joint move
        interp.plan_next(Drive(joint=1, target=0.3))
    assert "the SPEED setting in mm/s" in str(info.value) and "% or deg/s" in str(info.value)


def test_drive_moves_one_joint_only() -> None:
    seg = Interpreter(ROBOT, Q0).plan_next(Drive(joint=3, target=math.radians(120.0)))
    q = seg.sample(np.linspace(0.0, seg.duration, 50)).q
    others = [0, 1, 3, 4, 5]
    assert np.all(q[:, others] == Q0[others])
    assert math.isclose(q[-1, 2], math.radians(120.0))


def test_a_move_to_where_the_arm_is_takes_no_time() -> None:
    seg = Interpreter(ROBOT, Q0).plan_next(Move(joints=tuple(Q0)))
    assert seg.duration == 0.0
    np.testing.assert_array_equal(seg.sample(np.array([0.0, 1.0])).q, [Q0, Q0])


@pytest.mark.parametrize(
    ("statement", "reason", "text"),
    [
        (Move(joints=(0.0, 0.0, 0.0)), RefusalReason.INVALID, "has 6"),
        (Move(joints=(0.0, math.radians(60.0), 0.0, 0.0, 0.0, 0.0)), RefusalReason.JOINT_LIMIT, "J2 target 60.000 deg"),
        (Drive(joint=7, target=0.0), RefusalReason.INVALID, "J1..J6"),
        (Drive(joint=5, target=math.radians(-120.0)), RefusalReason.JOINT_LIMIT, "J5 target -120.000 deg"),
        (Move(joints=tuple(TARGET), speed=Speed(value=1.5, unit="fraction")), RefusalReason.INVALID, "above 100 %"),
    ],
)
def test_impossible_joint_moves_are_refused_with_a_reason(statement, reason: RefusalReason, text: str) -> None:
    interp = Interpreter(ROBOT, Q0)
    interp.plan_next(Move(joints=tuple(TARGET)))
    before = interp.state
    with pytest.raises(PlanRefused) as info:
        interp.plan_next(statement)
    assert info.value.reason is reason
    assert info.value.index == 1
    assert text in str(info.value) and str(info.value).startswith("statement 2:")
    assert interp.state is before  # a refusal changes nothing


def test_custom_limits_are_used_and_checked() -> None:
    slow = MotionLimits(joint_velocity=np.full(6, 0.1), joint_acceleration=np.full(6, 0.2))
    seg = Interpreter(ROBOT, Q0, limits=slow).plan_next(Move(joints=tuple(TARGET), speed=fraction(1.0)))
    assert math.isclose(seg.duration, expected_duration(TARGET - Q0, 1.0, slow), rel_tol=1e-12)
    with pytest.raises(InputError, match="3 joints"):
        Interpreter(ROBOT, Q0, limits=MotionLimits(joint_velocity=np.ones(3), joint_acceleration=np.ones(3)))
    with pytest.raises(InputError, match="positive"):
        MotionLimits(joint_velocity=np.zeros(6), joint_acceleration=np.ones(6))
