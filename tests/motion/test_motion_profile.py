"""The trapezoidal time law: starts and ends at rest, never exceeds its rate or its acceleration."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from shared.motion.profile import Trapezoid

rates = st.floats(min_value=1e-2, max_value=1e2, allow_nan=False, allow_infinity=False)


@given(rates, rates)
def test_profile_goes_from_rest_at_0_to_rest_at_1_within_its_bounds(velocity: float, accel: float) -> None:
    law = Trapezoid(velocity, accel)
    ts = np.linspace(0.0, law.duration, 2001)
    s, sd, sdd = law.evaluate(ts)
    assert s[0] == 0.0 and abs(s[-1] - 1.0) < 1e-12
    assert sd[0] == 0.0 and sd[-1] == 0.0
    assert np.all(np.diff(s) >= -1e-15)
    assert np.max(sd) <= velocity * (1 + 1e-12)
    assert np.max(np.abs(sdd)) <= accel * (1 + 1e-12)
    # the rate is the derivative of the position (trapezoid rule on a fine grid)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (sd[1:] + sd[:-1]) * np.diff(ts))])
    # exact on linear pieces; at each of the (up to 4) kinks it errs by at most accel * dt^2 / 4
    dt = ts[1] - ts[0]
    assert np.max(np.abs(integral - s)) <= accel * dt * dt + 1e-12


@given(rates, rates)
def test_duration_is_the_trapezoid_or_triangle_formula(velocity: float, accel: float) -> None:
    law = Trapezoid(velocity, accel)
    if velocity * velocity / accel < 1.0:
        expected = 1.0 / velocity + velocity / accel
    else:
        expected = 2.0 / math.sqrt(accel)
    assert math.isclose(law.duration, expected, rel_tol=1e-12)


def test_times_outside_the_motion_are_at_rest() -> None:
    law = Trapezoid(1.0, 2.0)
    s, sd, sdd = law.evaluate(np.array([-1.0, law.duration + 1.0]))
    assert s.tolist() == [0.0, 1.0] and sd.tolist() == [0.0, 0.0] and sdd.tolist() == [0.0, 0.0]
