"""Time law of a segment: the path parameter ``s`` from 0 to 1 on a trapezoidal velocity profile.

Every motion statement is a geometric path ``q(s)``, ``s`` in [0, 1], and one scalar time law
shared by all joints, so the joints start and arrive together (synchronised motion) and a
Cartesian path keeps its shape whatever the timing. The law accelerates at ``accel`` up to
``velocity``, cruises, and decelerates symmetrically; when ``s = 1`` is too short to reach
``velocity`` the profile is triangular.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True)
class Trapezoid:
    """``s(t)`` from 0 to 1 with peak rate ``velocity`` (1/s) and rate change ``accel`` (1/s^2)."""

    velocity: float
    accel: float

    @property
    def t_accel(self) -> float:
        """Length of the acceleration phase (s)."""
        return min(self.velocity / self.accel, np.sqrt(1.0 / self.accel))

    @property
    def peak(self) -> float:
        """Largest ``ds/dt`` reached (equals ``velocity`` unless the profile is triangular)."""
        return self.accel * self.t_accel

    @cached_property
    def duration(self) -> float:
        """Length of the whole law (s); computed once (a long program's views read it per line)."""
        ta = self.t_accel
        peak = self.accel * ta
        cruise = max(0.0, (1.0 - peak * ta) / peak)
        return 2.0 * ta + cruise

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``s``, ``ds/dt``, ``d2s/dt2`` at times ``t`` (clamped to [0, duration])."""
        return evaluate_trapezoids(np.asarray(t, dtype=float), self.velocity, self.accel)


def evaluate_trapezoids(
    t: np.ndarray, velocity: np.ndarray | float, accel: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Trapezoid.evaluate`` for many laws at once: ``velocity`` and ``accel`` may be arrays
    broadcast against ``t`` (one law per time), so a whole plan samples in one pass."""
    t = np.asarray(t, dtype=float)
    if t.size == 1 and np.ndim(velocity) == 0 and np.ndim(accel) == 0:
        return _evaluate_one(t, float(velocity), float(accel))
    a = np.asarray(accel, dtype=float)
    ta = np.minimum(velocity / a, np.sqrt(1.0 / a))
    peak = a * ta
    total = 2.0 * ta + np.maximum(0.0, (1.0 - peak * ta) / peak)
    tc = np.clip(t, 0.0, total)
    td = total - tc
    rising = tc < ta
    falling = tc > total - ta
    s = np.where(rising, 0.5 * a * tc * tc, np.where(falling, 1.0 - 0.5 * a * td * td, 0.5 * a * ta * ta + peak * (tc - ta)))
    sd = np.where(rising, a * tc, np.where(falling, a * td, peak))
    sdd = np.where(rising, a, np.where(falling, -a, 0.0))
    still = (t <= 0.0) | (t >= total)  # before and after the motion nothing moves
    return np.clip(s, 0.0, 1.0), np.where(still, 0.0, sd), np.where(still, 0.0, sdd)


def _evaluate_one(t: np.ndarray, velocity: float, a: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``evaluate_trapezoids`` at one time (a servo step), in floats; the same formulas."""
    ta = min(velocity / a, math.sqrt(1.0 / a))
    peak = a * ta
    total = 2.0 * ta + max(0.0, (1.0 - peak * ta) / peak)
    t0 = float(t.reshape(-1)[0])
    tc = min(max(t0, 0.0), total)
    td = total - tc
    if tc < ta:
        s, sd, sdd = 0.5 * a * tc * tc, a * tc, a
    elif tc > total - ta:
        s, sd, sdd = 1.0 - 0.5 * a * td * td, a * td, -a
    else:
        s, sd, sdd = 0.5 * a * ta * ta + peak * (tc - ta), peak, 0.0
    if t0 <= 0.0 or t0 >= total:
        sd = sdd = 0.0
    shape = t.shape
    return (np.full(shape, min(max(s, 0.0), 1.0)), np.full(shape, sd), np.full(shape, sdd))
