"""A seeded synthetic lunar terrain: regolith undulation, a regional slope, craters with raised
rims and ejecta, and half-buried rocks, sampled at random ground positions with sensor noise
like a stereo camera's cloud. Same arguments, same points, on every machine (numpy's PCG64).

The height field is public (``TerrainSpec.height``) so tests can compare a triangulated surface
with the truth it was sampled from.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shared.errors import InputError

DEFAULT_POINTS = 400_000


@dataclass(frozen=True)
class Crater:
    x: float
    y: float
    radius: float
    depth: float


@dataclass(frozen=True)
class Rock:
    x: float
    y: float
    a: float  # semi-axes on the ground (m)
    b: float
    yaw: float
    height: float  # visible height above the surrounding ground (m)


@dataclass(frozen=True)
class TerrainSpec:
    """A terrain's features; ``origin`` (x, y) and ``size`` (x, y) of the sampled area in metres."""

    seed: int
    origin: tuple[float, float]
    size: tuple[float, float]
    slope: tuple[float, float]  # dz/dx, dz/dy
    waves: np.ndarray = field(repr=False)  # (K, 4): kx, ky, phase, amplitude
    craters: tuple[Crater, ...] = ()
    rocks: tuple[Rock, ...] = ()

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Ground height z (m) at ground positions x, y (any equal shapes)."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        z = self.slope[0] * (x - self.origin[0]) + self.slope[1] * (y - self.origin[1])
        for kx, ky, phase, amp in self.waves:
            z = z + amp * np.sin(kx * x + ky * y + phase)
        for c in self.craters:
            r = np.hypot(x - c.x, y - c.y) / c.radius
            bowl = c.depth * (r * r - 1.0)  # parabolic floor, zero at the rim
            rim = 0.25 * c.depth * np.exp(-((r - 1.0) / 0.18) ** 2)  # raised rim
            ejecta = 0.25 * c.depth * np.where(r > 1.0, r ** -3.0, 1.0)
            z = z + np.where(r < 1.0, bowl + 0.25 * c.depth, ejecta) + rim
        for k in self.rocks:
            dx, dy = x - k.x, y - k.y
            c, s = np.cos(k.yaw), np.sin(k.yaw)
            u = (c * dx + s * dy) / k.a
            v = (-s * dx + c * dy) / k.b
            # a half-buried ellipsoid: the cap above ground, steep but not vertical at its foot
            cap = np.sqrt(np.clip(1.0 - u * u - v * v, 0.0, None))
            z = z + np.maximum(k.height * (cap - 0.35) / 0.65, 0.0)
        return z


def make_spec(
    seed: int = 4,
    origin: tuple[float, float] = (0.0, -1.0),
    size: tuple[float, float] = (2.0, 2.0),
    craters_per_m2: float = 1.5,
    rocks_per_m2: float = 6.0,
) -> TerrainSpec:
    """Draw a terrain's features from ``seed``: counts scale with the area."""
    if size[0] <= 0 or size[1] <= 0:
        raise InputError(f"terrain size must be positive, got {size}")
    rng = np.random.default_rng(seed)
    area = size[0] * size[1]
    slope = tuple(rng.uniform(-0.08, 0.08, 2))
    k = rng.uniform(2.0, 25.0, 6) * rng.choice([-1, 1], 6)
    theta = rng.uniform(0, np.pi, 6)
    waves = np.stack([k * np.cos(theta), k * np.sin(theta), rng.uniform(0, 2 * np.pi, 6), 0.04 / np.abs(k) * 6], axis=1)

    def inside(n: int) -> tuple[np.ndarray, np.ndarray]:
        return rng.uniform(origin[0], origin[0] + size[0], n), rng.uniform(origin[1], origin[1] + size[1], n)

    n_craters = max(1, int(round(craters_per_m2 * area)))
    cx, cy = inside(n_craters)
    radii = 0.05 + 0.35 * rng.power(0.4, n_craters)
    craters = tuple(Crater(float(a), float(b), float(r), float(r * rng.uniform(0.12, 0.22))) for a, b, r in zip(cx, cy, radii))
    n_rocks = max(1, int(round(rocks_per_m2 * area)))
    rx, ry = inside(n_rocks)
    rocks = []
    for a, b in zip(rx, ry):
        semi = 0.02 + 0.10 * rng.power(0.5)
        rocks.append(Rock(float(a), float(b), float(semi), float(semi * rng.uniform(0.6, 1.0)), float(rng.uniform(0, np.pi)),
                          float(semi * rng.uniform(0.5, 1.2))))
    return TerrainSpec(seed, tuple(origin), tuple(size), slope, waves, craters, tuple(rocks))  # type: ignore[arg-type]


def generate_points(spec: TerrainSpec, n_points: int = DEFAULT_POINTS, noise: float = 0.0005) -> np.ndarray:
    """``n_points`` samples (N, 3) of the terrain at uniform random ground positions, with
    Gaussian height noise of ``noise`` m (a stereo camera's range error)."""
    if n_points < 3:
        raise InputError(f"a terrain needs at least 3 points, got {n_points}")
    rng = np.random.default_rng((spec.seed, 1))
    x = rng.uniform(spec.origin[0], spec.origin[0] + spec.size[0], n_points)
    y = rng.uniform(spec.origin[1], spec.origin[1] + spec.size[1], n_points)
    z = spec.height(x, y) + rng.normal(0.0, noise, n_points)
    return np.stack([x, y, z], axis=1)


def generate_lunar_terrain(
    seed: int = 4, n_points: int = DEFAULT_POINTS, origin: tuple[float, float] = (0.0, -1.0),
    size: tuple[float, float] = (2.0, 2.0), noise: float = 0.0005,
) -> tuple[TerrainSpec, np.ndarray]:
    """The spec and its sampled cloud in one call."""
    spec = make_spec(seed, origin, size)
    return spec, generate_points(spec, n_points, noise)
