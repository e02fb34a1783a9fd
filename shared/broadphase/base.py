"""The common interface of the many-body detectors (thesis chapter 5) and the input checks.

Every detector answers the same question for one frame: which pairs of spheres (centre, radius)
overlap or touch, ``|c_i - c_j| <= r_i + r_j``. The answer is an ``(K, 2)`` int64 array of body
indices with ``i < j`` in each row, rows sorted lexicographically, so that any two methods can be
compared with ``np.array_equal``. Detectors may keep state between frames (that is the point of
the incremental ones), so a detector instance follows one scene.

The exact sphere predicate is written once (``sphere_overlap``) and every method, the brute force
reference included, evaluates the very same floating-point expression, so "exactly touching"
bodies are reported identically everywhere.
"""

from __future__ import annotations

import types
from abc import ABC, abstractmethod

import numpy as np
from numba import get_num_threads, njit, prange

from shared.errors import InputError

PAIR_DTYPE = np.int64


@njit(inline="always", cache=True)
def sphere_overlap(xi, yi, zi, ri, xj, yj, zj, rj) -> bool:
    """The one contact predicate: squared centre distance against squared radius sum."""
    dx = xi - xj
    dy = yi - yj
    dz = zi - zj
    s = ri + rj
    return dx * dx + dy * dy + dz * dz <= s * s


#: lanes of the running extremes in ``frame_stats``: 8 bodies of (x, y, z), so lane u holds
#: coordinate u % 3 (and for the radii, any 24 of them)
_LANES = 24
#: from this many bodies the frame's pass runs on every thread (measured on 2, caches flushed
#: as between benchmark frames: 100k bodies 0.14 ms against 0.27 for the former one-value-per-
#: coordinate loop, 1M 1.0 against 2.65 ms)
STATS_PARALLEL_MIN = 50_000


@njit(cache=True)  # not inlined: inlined twice into one loop it no longer vectorised (2x slower)
def _extremes(flat, j0, j1, lo, hi, bad):
    """Running minimum and maximum of ``flat[j0:j1]`` in _LANES independent lanes (element j
    in lane ``j % _LANES``; ``j0`` a multiple of _LANES), and a detector of non-finite values:
    ``v - v`` is NaN exactly for NaN and +-inf, so a lane of ``bad`` stays 0 only while its
    values are finite. A loop of constant inner length that LLVM vectorises; one running value
    per coordinate is a chain of dependent operations (2x slower). Unsigned indices: a signed
    one makes numba's wraparound compile the loads to gathers."""
    lanes = np.uint64(_LANES)
    nb = (j1 - j0) // lanes
    for b in range(nb):
        o = j0 + b * lanes
        for u in range(_LANES):
            v = flat[o + np.uint64(u)]
            lo[u] = v if v < lo[u] else lo[u]
            hi[u] = v if v > hi[u] else hi[u]
            bad[u] += v - v
    for j in range(j0 + nb * lanes, j1):
        u = j % lanes
        v = flat[j]
        lo[u] = v if v < lo[u] else lo[u]
        hi[u] = v if v > hi[u] else hi[u]
        bad[u] += v - v


@njit(parallel=True, cache=True)
def _frame_lanes(c, r, parts):
    """The lanes of ``_extremes`` for the centres and the radii, ``parts`` body ranges (each
    starting at a multiple of 8 bodies, so that lane u keeps coordinate u % 3)."""
    n = c.shape[0]
    flat = c.reshape(-1)
    lo = np.full((parts, _LANES), np.inf)
    hi = np.full((parts, _LANES), -np.inf)
    bad = np.zeros((parts, _LANES))
    rlo = np.full((parts, _LANES), np.inf)
    rhi = np.full((parts, _LANES), -np.inf)
    rbad = np.zeros((parts, _LANES))
    for t in prange(parts):
        b0 = (n * t // parts) // 8 * 8
        b1 = n if t == parts - 1 else (n * (t + 1) // parts) // 8 * 8
        _extremes(flat, np.uint64(3 * b0), np.uint64(3 * b1), lo[t], hi[t], bad[t])
        _extremes(r, np.uint64(b0), np.uint64(b1), rlo[t], rhi[t], rbad[t])
    return lo, hi, bad, rlo, rhi, rbad


def serial_twin(py_func):
    """The same code as a function of its own name (``<name>_serial``), for a serial compilation
    of a parallel kernel. Numba's cache files are named by module, qualified name and line, and
    its index keys hold neither ``parallel`` nor the other options, so a serial compilation of the
    kernel's own function would share the parallel one's files, each process loading whichever
    was saved first; the twin's files are its own (``cache=True`` on both: set-up compiles them
    once, ``shared.broadphase.warm_up``, and every later process loads them)."""
    twin = types.FunctionType(py_func.__code__, py_func.__globals__, py_func.__name__ + "_serial", py_func.__defaults__,
                              py_func.__closure__)
    twin.__qualname__ = py_func.__qualname__ + "_serial"
    twin.__module__ = py_func.__module__
    twin.__kwdefaults__ = py_func.__kwdefaults__
    twin.__doc__ = py_func.__doc__
    return twin


_frame_lanes_serial = njit(cache=True)(serial_twin(_frame_lanes.py_func))


@njit(cache=True)
def _combine(n, lo, hi, bad, rlo, rhi, rbad):
    ok = True
    lo3 = np.full(3, np.inf)
    hi3 = np.full(3, -np.inf)
    rmin = np.inf
    rmax = 0.0
    for t in range(lo.shape[0]):
        for u in range(_LANES):
            k = u % 3
            lo3[k] = min(lo3[k], lo[t, u])
            hi3[k] = max(hi3[k], hi[t, u])
            rmin = min(rmin, rlo[t, u])
            rmax = max(rmax, rhi[t, u])
            ok &= (bad[t, u] == 0.0) & (rbad[t, u] == 0.0)
    ok &= rmin >= 0.0
    amax = 0.0
    if n > 0:
        amax = max(max(abs(lo3[0]), abs(lo3[1]), abs(lo3[2])), max(abs(hi3[0]), abs(hi3[1]), abs(hi3[2])))
    return ok, lo3, hi3, amax, rmax


def frame_stats(c: np.ndarray, r: np.ndarray):
    """One pass over a frame (C-contiguous float64 ``c`` (N, 3), ``r`` (N,)): (finite and radii
    >= 0, lower corner (3,), upper corner (3,), largest |coordinate|, largest radius).
    Replaces a dozen numpy reductions per frame; on every thread from STATS_PARALLEL_MIN
    bodies."""
    n = c.shape[0]
    if n >= STATS_PARALLEL_MIN:
        lanes = _frame_lanes(c, r, 2 * max(1, get_num_threads()))
    else:
        lanes = _frame_lanes_serial(c, r, 1)
    return _combine(n, *lanes)


def pad_for(amax: float, rmax: float) -> float:
    """A tiny widening of every box so that box tests never reject a pair the sphere test
    accepts through rounding (``x_j - r_j <= x_i + r_i`` and ``|x_i - x_j| <= r_i + r_j`` can
    disagree in the last bit). Boxes only prune; the sphere predicate decides. ``amax`` is the
    largest |coordinate|, ``rmax`` the largest radius."""
    return (amax + rmax + 1.0) * 1e-12


def check_bodies(centres: object, radii: object) -> tuple[np.ndarray, np.ndarray]:
    """Validate and convert one frame: ``centres`` (N, 3) finite, ``radii`` (N,) or a scalar,
    non-negative and finite. Returns contiguous float64 arrays."""
    c = np.ascontiguousarray(centres, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3:
        raise InputError(f"centres must have shape (N, 3), got {c.shape}")
    n = c.shape[0]
    r = np.asarray(radii, dtype=np.float64)
    if r.ndim == 0:
        r = np.full(n, float(r))
    r = np.ascontiguousarray(r)
    if r.shape != (n,):
        raise InputError(f"radii must have shape ({n},) to match the centres, got {r.shape}")
    return c, r


class Frame:
    """A checked frame with the statistics every method needs (one pass, see frame_stats)."""

    __slots__ = ("centres", "radii", "lo", "hi", "rmax", "pad")

    def __init__(self, centres: object, radii: object) -> None:
        c, r = check_bodies(centres, radii)
        ok, lo, hi, amax, rmax = frame_stats(c, r)
        if not ok:
            raise InputError("centres and radii must be finite and radii non-negative")
        self.centres, self.radii = c, r
        self.lo, self.hi, self.rmax = lo, hi, float(rmax)
        self.pad = pad_for(float(amax), self.rmax)


#: widest digit of the radix sort in ``sort_pairs`` (buckets: 2^13 at most)
_RADIX_BITS = 13


@njit(cache=True)
def _sorted_pairs(pairs, n):
    """Rows in (min, max) order, sorted by the key ``min << s | max`` (``s`` the bits of n - 1:
    decoding is a shift and a mask, where ``min * n + max`` took a 64-bit division a row) with
    a least-significant-digit radix sort: as few passes as digits of up to _RADIX_BITS allow,
    every pass's histogram counted in one read of the keys (measured 3.4x numpy's sort at 8,700
    pairs, 8x at 110,000 before these two changes, which took a further quarter off at 11,000
    and a tenth at 110,000)."""
    m = pairs.shape[0]
    s = 1
    while (np.int64(1) << s) < n:
        s += 1
    bits = 2 * s
    passes = (bits + _RADIX_BITS - 1) // _RADIX_BITS
    width = (bits + passes - 1) // passes
    digits = 1 << width
    mask = digits - 1
    key = np.empty(m, np.int64)
    count = np.zeros((passes, digits + 1), np.int64)
    for i in range(m):
        a = np.int64(pairs[i, 0])
        b = np.int64(pairs[i, 1])
        k = (min(a, b) << s) | max(a, b)
        key[i] = k
        for p in range(passes):
            count[p, ((k >> (p * width)) & mask) + 1] += 1
    tmp = np.empty(m, np.int64)
    for p in range(passes):
        c = count[p]
        for d in range(digits):
            c[d + 1] += c[d]
        shift = p * width
        for i in range(m):
            d = (key[i] >> shift) & mask
            tmp[c[d]] = key[i]
            c[d] += 1
        key, tmp = tmp, key
    out = np.empty((m, 2), PAIR_DTYPE)
    low = (np.int64(1) << s) - 1
    for i in range(m):
        out[i, 0] = key[i] >> s
        out[i, 1] = key[i] & low
    return out


def sort_pairs(pairs: np.ndarray, n: int) -> np.ndarray:
    """Put each row in ``(min, max)`` order and the rows in lexicographic order (one int64 key
    per row, so a single sort)."""
    if pairs.shape[0] == 0:
        return np.zeros((0, 2), dtype=PAIR_DTYPE)
    return _sorted_pairs(pairs, int(n))


class Detector(ABC):
    """One many-body detector following one scene frame after frame."""

    #: short name used by the benchmark and the registry
    name: str = ""

    def update(self, centres: object, radii: object) -> np.ndarray:
        """Overlapping pairs of this frame, ``(K, 2)`` int64, ``i < j``, sorted."""
        frame = Frame(centres, radii)
        if frame.centres.shape[0] < 2:
            return np.zeros((0, 2), dtype=PAIR_DTYPE)
        return self._update(frame)

    @abstractmethod
    def _update(self, frame: Frame) -> np.ndarray:
        """Checked input (``Frame``), at least two bodies."""

    def reset(self) -> None:
        """Forget anything kept from earlier frames (a new scene follows)."""
