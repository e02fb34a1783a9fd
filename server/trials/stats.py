"""The statistics a trial table shows: medians and inter-quartile ranges of times, and success
rates with Wilson score intervals (exact enough at 20 runs, never outside [0, 1], and not zero
wide at 0 or 20 successes as the normal approximation is)."""

from __future__ import annotations

import math
from statistics import median, quantiles

Z95 = 1.959963984540054  # the standard normal's 97.5 % point


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float] | None:
    """The Wilson score interval of a binomial proportion (95 % by default); None for n = 0."""
    if n <= 0:
        return None
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be within 0..{n}; got {successes}")
    p = successes / n
    z2 = z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def med(values: list[float]) -> float | None:
    return round(median(values), 4) if values else None


def iqr(values: list[float]) -> tuple[float, float] | None:
    """First and third quartiles (inclusive method); a single value is its own range."""
    if not values:
        return None
    if len(values) == 1:
        return (round(values[0], 4), round(values[0], 4))
    q1, _, q3 = quantiles(values, n=4, method="inclusive")
    return (round(q1, 4), round(q3, 4))
