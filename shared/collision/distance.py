"""Exact distance between triangles, compiled with numba.

For two disjoint triangles the closest pair is either an edge-edge pair or a vertex of one and
a point of the other's face, so the distance is the minimum of 9 segment-segment distances and
6 point-triangle distances. Triangles that intersect have distance 0 (the scene calls this only
for body pairs already found apart; ``tri_tri_distance_np`` checks intersection first).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shared.collision.tri_tri import (
    JIT,
    _degenerate,
    _tup,
    add,
    cross,
    dot,
    norm2,
    scale,
    seg_seg_closest,
    sub,
    tri_tri_intersect,
)


@njit(**JIT)
def closest_point_on_triangle(p, a, b, c):
    """Closest point to p on the (non-degenerate) triangle abc (Ericson 5.1.5)."""
    ab = sub(b, a)
    ac = sub(c, a)
    ap = sub(p, a)
    d1 = dot(ab, ap)
    d2 = dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return a
    bp = sub(p, b)
    d3 = dot(ab, bp)
    d4 = dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return add(a, scale(ab, v))
    cp = sub(p, c)
    d5 = dot(ab, cp)
    d6 = dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return add(a, scale(ac, w))
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return add(b, scale(sub(c, b), w))
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return add(a, add(scale(ab, v), scale(ac, w)))


@njit(**JIT)
def _edge(p0, p1, p2, i):
    if i == 0:
        return p0, p1
    if i == 1:
        return p1, p2
    return p2, p0


@njit(**JIT)
def tri_tri_dist2(p0, p1, p2, q0, q1, q2):
    """Squared distance and closest points (on p, on q) of two disjoint triangles."""
    best = np.inf
    bp = p0
    bq = q0
    for i in range(3):
        a, b = _edge(p0, p1, p2, i)
        for j in range(3):
            c, d = _edge(q0, q1, q2, j)
            d2, x, y = seg_seg_closest(a, b, c, d)
            if d2 < best:
                best = d2
                bp = x
                bq = y
    n_q = cross(sub(q1, q0), sub(q2, q0))
    if not _degenerate(q0, q1, q2, n_q):
        for i in range(3):
            if i == 0:
                v = p0
            elif i == 1:
                v = p1
            else:
                v = p2
            y = closest_point_on_triangle(v, q0, q1, q2)
            d2 = norm2(sub(v, y))
            if d2 < best:
                best = d2
                bp = v
                bq = y
    n_p = cross(sub(p1, p0), sub(p2, p0))
    if not _degenerate(p0, p1, p2, n_p):
        for i in range(3):
            if i == 0:
                v = q0
            elif i == 1:
                v = q1
            else:
                v = q2
            x = closest_point_on_triangle(v, p0, p1, p2)
            d2 = norm2(sub(v, x))
            if d2 < best:
                best = d2
                bp = x
                bq = v
    return best, bp, bq


def tri_tri_distance_np(p: np.ndarray, q: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Distance between two triangles given as ``(3, 3)`` arrays, with the closest points.

    Intersecting triangles give ``(0.0, nan, nan)``: they have no unique witness pair.
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pt = (_tup(p[0]), _tup(p[1]), _tup(p[2]))
    qt = (_tup(q[0]), _tup(q[1]), _tup(q[2]))
    if tri_tri_intersect(*pt, *qt):
        nan = np.full(3, np.nan)
        return 0.0, nan, nan.copy()
    d2, x, y = tri_tri_dist2(*pt, *qt)
    return float(np.sqrt(d2)), np.array(x), np.array(y)


@njit(**JIT)
def _quad_pair_distance(a, b):
    """Distance between two planar quads (4 corners each, in order round the edge), each split
    into two triangles: 0 when they meet."""
    best = np.inf
    for i in range(2):
        p0 = (a[0, 0], a[0, 1], a[0, 2])
        p1 = (a[1 + i, 0], a[1 + i, 1], a[1 + i, 2])
        p2 = (a[2 + i, 0], a[2 + i, 1], a[2 + i, 2])
        for j in range(2):
            q0 = (b[0, 0], b[0, 1], b[0, 2])
            q1 = (b[1 + j, 0], b[1 + j, 1], b[1 + j, 2])
            q2 = (b[2 + j, 0], b[2 + j, 1], b[2 + j, 2])
            if tri_tri_intersect(p0, p1, p2, q0, q1, q2):
                return 0.0
            d2, _x, _y = tri_tri_dist2(p0, p1, p2, q0, q1, q2)
            if d2 < best:
                best = d2
    return np.sqrt(best)


@njit(**JIT)
def quad_pair_distances(a, b):
    """Distances between quads ``a[k]`` and ``b[k]`` (``(n, 4, 3)`` arrays of corners): the
    contact test of feature faces (``shared.tasknet.contacts``)."""
    n = a.shape[0]
    out = np.empty(n)
    for k in range(n):
        out[k] = _quad_pair_distance(a[k], b[k])
    return out
