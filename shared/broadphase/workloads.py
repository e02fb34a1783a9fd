"""The particle-sedimentation workload of thesis §5.2.5 and clustered variants.

Bodies are spheres in a cube of side ``L`` (``density = N / L^3``); every frame each body moves
``speed`` (length units per frame, the thesis's SPEED) along its own random direction and is
reflected by the walls. The thesis's experiments: Table 5.1 density 0.0005 and SPEED 0.5 with
N = 16..2048; Table 5.2 N = 256, SPEED 0.5, L = 16..256; Table 5.3 N = 512, L = 100, SPEED
0.1..12.8. The thesis does not give the sphere size; radius 1 (diameter 2) is used, which makes
Table 5.2's L = 16 a dense scene (256 spheres of volume 4.2 in 4096).

Clustered variants keep the bodies where non-uniform subdivision should pay: ``gaussian``
(several Gaussian clouds in a mostly empty cube, each body drawn back toward its cloud's
centre) and ``sediment`` (a dense layer near the floor under a sparse suspension; bodies in the
layer stay in it). Everything is seeded; a scene is advanced with ``step``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shared.errors import InputError, UnknownNameError

THESIS_DENSITY = 0.0005
THESIS_SPEED = 0.5
KINDS = ("uniform", "gaussian", "sediment")


@dataclass
class Scene:
    """A moving set of spheres in ``[0, L]^3``. ``centres`` (N, 3), ``radii`` (N,),
    ``directions`` unit vectors (N, 3). In clustered scenes each body has a home box
    (``home_lo``, ``home_hi``, (N, 3)); outside it, the direction components leading further
    away are reversed, so the clusters persist while every body keeps moving at ``speed``."""

    centres: np.ndarray
    radii: np.ndarray
    directions: np.ndarray
    size: float
    speed: float
    home_lo: np.ndarray | None = None
    home_hi: np.ndarray | None = None
    kind: str = "uniform"
    frame: int = field(default=0)

    @property
    def n(self) -> int:
        return int(self.centres.shape[0])

    @property
    def density(self) -> float:
        return self.n / self.size**3

    def step(self) -> None:
        """Advance one frame: move ``speed`` along each direction, reflect at the walls."""
        c = self.centres
        d = self.directions
        c += self.speed * d
        r = self.radii[:, None]
        low = c < r
        high = c > self.size - r
        np.copyto(c, 2.0 * r - c, where=low)
        np.copyto(c, 2.0 * (self.size - r) - c, where=high)
        np.clip(c, r, self.size - r, out=c)
        flip = (low & (d < 0)) | (high & (d > 0))
        if self.home_lo is not None:
            flip |= ((c < self.home_lo) & (d < 0)) | ((c > self.home_hi) & (d > 0))
        d[flip] = -d[flip]
        self.frame += 1


def _unit_vectors(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return v


def side_for(n: int, density: float) -> float:
    """Cube side giving ``n`` bodies at ``density`` bodies per unit volume."""
    return float((n / density) ** (1.0 / 3.0))


def make_scene(kind: str = "uniform", n: int = 512, size: float | None = None,
               density: float = THESIS_DENSITY, speed: float = THESIS_SPEED, radius: float = 1.0,
               radius_spread: float = 0.0, seed: int = 0, clusters: int = 6) -> Scene:
    """A seeded scene. ``size`` (the cube side L) wins over ``density``; ``radius_spread`` > 0
    draws radii uniformly in ``radius * [1 - spread, 1]``. Clustered kinds keep the overall
    density of the cube (so they compare with the uniform scene of the same N and L) but put
    the bodies in a small part of it."""
    if kind not in KINDS:
        raise UnknownNameError("scene kind", kind, KINDS)
    if n < 0:
        raise InputError(f"number of bodies must be >= 0, got {n}")
    if not (radius > 0) or not (0 <= radius_spread < 1):
        raise InputError("radius must be > 0 and radius_spread in [0, 1)")
    L = float(size) if size is not None else side_for(max(n, 1), density)
    if L <= 2 * radius:
        raise InputError(f"space size L = {L} must exceed the sphere diameter {2 * radius}")
    rng = np.random.default_rng(seed)
    radii = radius * (1.0 - radius_spread * rng.random(n))
    home_lo = home_hi = None
    lo, hi = radius, L - radius
    if kind == "uniform":
        c = rng.uniform(lo, hi, size=(n, 3))
    elif kind == "gaussian":
        k = max(1, clusters)
        homes = rng.uniform(0.2 * L, 0.8 * L, size=(k, 3))
        sig = L * rng.uniform(0.06, 0.10, size=k)  # cluster cores ~10-40x the mean density
        label = rng.integers(0, k, size=n)
        c = homes[label] + rng.normal(size=(n, 3)) * sig[label][:, None]
        home_lo = homes[label] - 2.5 * sig[label][:, None]
        home_hi = homes[label] + 2.5 * sig[label][:, None]
    else:  # sediment: 80% of the bodies in a floor layer 5% of the height thick
        layer = rng.random(n) < 0.8
        c = rng.uniform(lo, hi, size=(n, 3))
        h = 0.05 * L
        c[layer, 2] = rng.uniform(lo, max(lo, h), size=int(layer.sum()))
        home_lo = np.full((n, 3), -np.inf)
        home_hi = np.full((n, 3), np.inf)
        home_hi[layer, 2] = h
    c = np.ascontiguousarray(np.clip(c, radii[:, None], L - radii[:, None]))
    return Scene(c, radii, _unit_vectors(rng, n), L, float(speed), home_lo, home_hi, kind)
