"""Key points of a sampled tool path (thesis §3.3.3): where an action-level task model puts its
states.

In free motion an action runs from a start point to a goal point, in a straight line or along
one direction, and the robot rests between actions; the states of the model ``s0 a1 s1 ... an sn``
are the path's key points. The thesis finds them in three steps, done here on a digital curve
``C = p_1 ... p_n`` (with sample times when there are any):

1. **Arc radius from chord and height** in each point's k-neighbourhood
   ``R_k(p_i) = {p_{i-k} ... p_{i+k}}`` (Definition 3.8): the chord ``l = |p_{i-k} p_{i+k}|``, its
   height ``h`` (the thesis's ``|p_i p_i'|`` to the chord's midpoint ``p_i'``; here the distance
   to the chord's line, the same on an evenly sampled arc and 0 on a straight line however it
   was sampled), and the radius of the arc through
   them ``R = l^2 / (8 h) + h / 2`` (from ``l = 2 R sin(theta)``, ``h = R - R cos(theta)``). A
   curve is taken as planar arcs joined end to end; a small radius is a sharp bend.
2. **Segmentation by curvature**: a run of points whose radius is below ``corner_radius`` is a
   bend; its point of least radius is a corner (a key point). The robot's rests (speed under
   ``stop_speed`` for at least ``stop_min_s``) split the path too: the points where it stops
   and where it moves again are key points.
3. **Piecewise-linear approximation** of each piece between those points: a chord
   ``L = p_a p_b`` approximates the points between under the thesis's error
   ``E = sum_i |p_i p_i^L|`` (each point's distance to the segment); while ``E`` exceeds
   ``error_bound`` the piece is split at its point farthest from the chord. The ends of the
   pieces are key points.

The error bound is one figure for the whole path (the thesis ties it to each piece's curvature
without giving the rule); a path sampled more densely sums more distances, so ``E`` is counted as
if the piece were sampled once per ``error_spacing`` of its length (``E`` times the mean sample
spacing over ``error_spacing``) before it is compared with ``error_bound``.
Pure numpy; the distances of a piece are computed at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from shared.errors import InputError

KeyKind = Literal["start", "end", "corner", "stop", "move", "split"]


@dataclass(frozen=True)
class KeyPointSettings:
    k: int = 5
    """half-length of the neighbourhood, samples"""
    corner_radius: float = 0.01
    """m: a bend sharper than this (arc radius below it) is a corner"""
    error_bound: float = 0.05
    """m: the thesis's E allowed for one linear piece, counted at one sample per ``error_spacing``"""
    error_spacing: float = 0.001
    """m: the sample spacing ``error_bound`` is counted at"""
    stop_speed: float = 0.002
    """m/s: slower than this the tool rests"""
    stop_min_s: float = 0.15
    """s: a rest shorter than this is not a stop"""


@dataclass(frozen=True)
class KeyPoint:
    index: int
    """the sample of the path"""
    t: float
    """its time, s (the index when the path has no times)"""
    position: tuple[float, float, float]
    """m"""
    kind: KeyKind


def arc_radii(points: np.ndarray, k: int) -> np.ndarray:
    """Each point's arc radius from chord length and chord height in its k-neighbourhood (m;
    ``inf`` where the neighbourhood is straight or does not fit inside the path). Repeated
    points (the tool resting) count once: a point repeating the one before takes its radius."""
    p = np.asarray(points, dtype=float)
    if len(p) > 1:
        moved = np.r_[True, np.linalg.norm(np.diff(p, axis=0), axis=1) > 1e-12]
        if not moved.all():
            return _radii(p[moved], k)[np.cumsum(moved) - 1]
    return _radii(p, k)


def _radii(p: np.ndarray, k: int) -> np.ndarray:
    n = len(p)
    radii = np.full(n, np.inf)
    if n < 2 * k + 1 or k < 1:
        return radii
    a, b, mid = p[: n - 2 * k], p[2 * k:], p[k: n - k]
    ab = b - a
    chord = np.linalg.norm(ab, axis=1)
    # the height off the chord's line: for samples evenly spaced on an arc this is the thesis's
    # |p_i p_i'| (p_i' the chord's midpoint); unlike it, it stays 0 on a straight line sampled
    # unevenly (a drag that slows down), where p_i is not at the midpoint
    with np.errstate(divide="ignore", invalid="ignore"):
        u = ab / chord[:, None]
    along = np.einsum("ij,ij->i", mid - a, np.nan_to_num(u))
    height = np.linalg.norm(mid - a - along[:, None] * np.nan_to_num(u), axis=1)
    height[chord < 1e-12] = np.inf  # the neighbourhood folds back on itself: a turn-around
    with np.errstate(divide="ignore", invalid="ignore"):
        r = chord**2 / (8.0 * height) + 0.5 * height
    r[height < 1e-12] = np.inf
    r[chord < 1e-12] = 0.0
    radii[k: n - k] = r
    return radii


def chord_error(points: np.ndarray) -> tuple[float, int]:
    """The thesis's ``E``: summed distance of the inner points to the segment between the ends,
    and the index of the farthest inner point (-1 when there is none)."""
    p = np.asarray(points, dtype=float)
    if len(p) < 3:
        return 0.0, -1
    a, b = p[0], p[-1]
    ab = b - a
    length2 = float(ab @ ab)
    inner = p[1:-1]
    if length2 < 1e-24:
        d = np.linalg.norm(inner - a, axis=1)
    else:
        s = np.clip((inner - a) @ ab / length2, 0.0, 1.0)
        d = np.linalg.norm(inner - (a + s[:, None] * ab), axis=1)
    return float(d.sum()), int(np.argmax(d)) + 1


def _stops(p: np.ndarray, t: np.ndarray, s: KeyPointSettings) -> list[tuple[int, int]]:
    """Index ranges ``[i, j]`` where the tool rests at least ``stop_min_s``."""
    if len(p) < 2:
        return []
    dt = np.diff(t)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(dt > 0, step / np.where(dt > 0, dt, 1.0), np.where(step > 0, np.inf, 0.0))
    slow = speed < s.stop_speed  # slow[i]: between samples i and i + 1
    return [(i, j) for i, j in _runs(slow) if t[j] - t[i] >= s.stop_min_s]


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(i, j)`` for each run of True in ``mask``: ``mask[i:j]`` all True, maximal."""
    edges = np.diff(np.r_[0, np.asarray(mask, dtype=np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def _corners(radii: np.ndarray, lo: int, hi: int, s: KeyPointSettings) -> list[int]:
    """The sharpest point of each bend (run of radius < corner_radius) strictly inside [lo, hi]."""
    out = []
    for i, j in _runs(radii[lo: hi + 1] < s.corner_radius):
        c = lo + i + int(np.argmin(radii[lo + i: lo + j]))
        if lo < c < hi:
            out.append(c)
    return out


def _linearise(p: np.ndarray, a: int, b: int, s: KeyPointSettings, out: list[int]) -> None:
    """Split ``[a, b]`` until each piece's ``E`` is within the bound; adds the split indices."""
    stack = [(a, b)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        error, far = chord_error(p[i: j + 1])
        length = float(np.linalg.norm(np.diff(p[i: j + 1], axis=0), axis=1).sum())
        # the thesis's E as if sampled once per error_spacing of path
        if error * (length / (j - i)) / s.error_spacing <= s.error_bound:
            continue
        m = i + far
        out.append(m)
        stack += [(i, m), (m, j)]


def key_points(points, times=None, settings: KeyPointSettings | None = None) -> list[KeyPoint]:
    """The key points of a sampled path (see the module docstring), in path order."""
    s = settings or KeyPointSettings()
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"a path is n points of 3 coordinates; got an array of shape {p.shape}")
    if not np.isfinite(p).all():
        raise InputError(f"path point {int(np.flatnonzero(~np.isfinite(p).all(axis=1))[0])} is not finite")
    n = len(p)
    if n == 0:
        return []
    t = np.arange(n, dtype=float) if times is None else np.asarray(times, dtype=float)
    if t.shape != (n,) or (np.diff(t) < 0).any():
        raise InputError("path times must be one per point and never decrease")
    kinds: dict[int, KeyKind] = {0: "start", n - 1: "end"}
    stops = _stops(p, t, s) if times is not None else []
    for i, j in stops:
        for index, kind in ((i, "stop"), (j, "move")):
            if 0 < index < n - 1:
                kinds.setdefault(index, kind)

    def moving_pieces() -> list[tuple[int, int]]:
        """Consecutive key points so far, without the spans where the tool rests."""
        breaks = sorted(kinds)
        return [(a, b) for a, b in zip(breaks, breaks[1:]) if not any(i <= a and b <= j for i, j in stops)]

    radii = arc_radii(p, s.k)
    for a, b in moving_pieces():
        for c in _corners(radii, a, b, s):
            kinds.setdefault(c, "corner")
    for a, b in moving_pieces():
        found: list[int] = []
        _linearise(p, a, b, s, found)
        for m in found:
            kinds.setdefault(m, "split")
    return [KeyPoint(index=i, t=float(t[i]), position=(float(p[i, 0]), float(p[i, 1]), float(p[i, 2])), kind=kinds[i])
            for i in sorted(kinds)]
