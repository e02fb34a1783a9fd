"""Exact triangle-triangle intersection (closed triangles), compiled with numba.

Points are passed as 3-tuples of floats (stack values in numba, no allocation). The test is
sign based: the plane of each triangle classifies the other's vertices (Moeller's early
rejection); then, for non-coplanar triangles, two triangles meet iff an edge of one meets the
other (each end of the intersection segment lies on an edge of one of them), and an edge meets
a triangle iff it reaches the plane and the line through it passes inside the three edges
(triple-product signs, as in Guigue-Devillers). Coplanar triangles, and edges lying in the other
triangle's plane, are tested in 2D after dropping the dominant axis of the normal.

Closed sets: touching (a shared vertex, a shared edge, a face resting on a face) counts as
intersecting. Degenerate triangles (zero area) are tested as their longest edge (or a point).

``tri_tri_intersect_np`` takes numpy arrays for tests and Python callers.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

JIT = dict(cache=True, nogil=True, fastmath=False)

#: a triangle whose |normal|^2 is below this times (longest edge)^4 is treated as a segment
DEGENERATE_REL = 1e-24


@njit(**JIT)
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(**JIT)
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(**JIT)
def scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@njit(**JIT)
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(**JIT)
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(**JIT)
def norm2(a):
    return a[0] * a[0] + a[1] * a[1] + a[2] * a[2]


@njit(**JIT)
def _drop_axis(n):
    """Index of the largest |component| of n: the axis dropped when projecting to 2D."""
    ax, ay, az = abs(n[0]), abs(n[1]), abs(n[2])
    if ax >= ay and ax >= az:
        return 0
    if ay >= az:
        return 1
    return 2


@njit(**JIT)
def _p2(a, k):
    if k == 0:
        return (a[1], a[2])
    if k == 1:
        return (a[2], a[0])
    return (a[0], a[1])


@njit(**JIT)
def orient2d(a, b, c):
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


@njit(**JIT)
def _on_segment_2d(a, b, p):
    """p collinear with ab (caller checked): is it within the closed segment's box?"""
    return (min(a[0], b[0]) <= p[0] <= max(a[0], b[0])) and (min(a[1], b[1]) <= p[1] <= max(a[1], b[1]))


@njit(**JIT)
def seg_seg_2d(a, b, c, d):
    """Closed 2D segments ab and cd meet."""
    o1 = orient2d(a, b, c)
    o2 = orient2d(a, b, d)
    o3 = orient2d(c, d, a)
    o4 = orient2d(c, d, b)
    if ((o1 > 0 and o2 < 0) or (o1 < 0 and o2 > 0)) and ((o3 > 0 and o4 < 0) or (o3 < 0 and o4 > 0)):
        return True
    if o1 == 0 and _on_segment_2d(a, b, c):
        return True
    if o2 == 0 and _on_segment_2d(a, b, d):
        return True
    if o3 == 0 and _on_segment_2d(c, d, a):
        return True
    if o4 == 0 and _on_segment_2d(c, d, b):
        return True
    return False


@njit(**JIT)
def point_in_tri_2d(p, a, b, c):
    """Closed 2D triangle abc (either orientation, non-degenerate) contains p."""
    s0 = orient2d(a, b, p)
    s1 = orient2d(b, c, p)
    s2 = orient2d(c, a, p)
    return (s0 >= 0 and s1 >= 0 and s2 >= 0) or (s0 <= 0 and s1 <= 0 and s2 <= 0)


@njit(**JIT)
def _seg_tri_2d(a, b, t0, t1, t2):
    if point_in_tri_2d(a, t0, t1, t2) or point_in_tri_2d(b, t0, t1, t2):
        return True
    return seg_seg_2d(a, b, t0, t1) or seg_seg_2d(a, b, t1, t2) or seg_seg_2d(a, b, t2, t0)


@njit(**JIT)
def _coplanar_tri_tri(p0, p1, p2, q0, q1, q2, n):
    k = _drop_axis(n)
    a0, a1, a2 = _p2(p0, k), _p2(p1, k), _p2(p2, k)
    b0, b1, b2 = _p2(q0, k), _p2(q1, k), _p2(q2, k)
    if point_in_tri_2d(a0, b0, b1, b2) or point_in_tri_2d(b0, a0, a1, a2):
        return True
    for i in range(3):
        if i == 0:
            s, e = a0, a1
        elif i == 1:
            s, e = a1, a2
        else:
            s, e = a2, a0
        if seg_seg_2d(s, e, b0, b1) or seg_seg_2d(s, e, b1, b2) or seg_seg_2d(s, e, b2, b0):
            return True
    return False


@njit(**JIT)
def _seg_tri(a, b, da, db, t0, t1, t2, n):
    """Closed segment ab meets the non-degenerate triangle t (normal n); da, db are the signed
    plane values of a and b (dot(n, x - t0)), computed once by the caller."""
    if (da > 0 and db > 0) or (da < 0 and db < 0):
        return False
    if da == 0 and db == 0:
        k = _drop_axis(n)
        return _seg_tri_2d(_p2(a, k), _p2(b, k), _p2(t0, k), _p2(t1, k), _p2(t2, k))
    ab = sub(b, a)
    v0, v1, v2 = sub(t0, a), sub(t1, a), sub(t2, a)
    s0 = dot(ab, cross(v0, v1))
    s1 = dot(ab, cross(v1, v2))
    s2 = dot(ab, cross(v2, v0))
    return (s0 >= 0 and s1 >= 0 and s2 >= 0) or (s0 <= 0 and s1 <= 0 and s2 <= 0)


@njit(**JIT)
def _degenerate(a, b, c, n):
    l0 = norm2(sub(b, a))
    l1 = norm2(sub(c, b))
    l2 = norm2(sub(a, c))
    lmax = max(l0, l1, l2)
    return norm2(n) <= DEGENERATE_REL * lmax * lmax


@njit(**JIT)
def _longest_edge(a, b, c):
    l0 = norm2(sub(b, a))
    l1 = norm2(sub(c, b))
    l2 = norm2(sub(a, c))
    if l0 >= l1 and l0 >= l2:
        return a, b
    if l1 >= l2:
        return b, c
    return c, a


@njit(**JIT)
def seg_seg_closest(p1, q1, p2, q2):
    """Closest points of segments p1q1 and p2q2 (Ericson 5.1.9): (dist^2, c1, c2)."""
    d1 = sub(q1, p1)
    d2 = sub(q2, p2)
    r = sub(p1, p2)
    a = dot(d1, d1)
    e = dot(d2, d2)
    f = dot(d2, r)
    eps = 1e-300
    if a <= eps and e <= eps:
        return norm2(r), p1, p2
    if a <= eps:
        s = 0.0
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = dot(d1, r)
        if e <= eps:
            t = 0.0
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = dot(d1, d2)
            denom = a * e - b * b
            if denom > 0.0:
                s = min(max((b * f - c * e) / denom, 0.0), 1.0)
            else:
                s = 0.0
            tnom = b * s + f
            if tnom < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif tnom > e:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
            else:
                t = tnom / e
    c1 = add(p1, scale(d1, s))
    c2 = add(p2, scale(d2, t))
    return norm2(sub(c1, c2)), c1, c2


@njit(**JIT)
def _seg_seg_touch(a, b, c, d):
    d2, _, _ = seg_seg_closest(a, b, c, d)
    scale2 = max(norm2(sub(b, a)), norm2(sub(d, c)), 1e-300)
    return d2 <= 1e-28 * scale2


@njit(**JIT)
def _seg_vs_tri(a, b, t0, t1, t2, n):
    da = dot(n, sub(a, t0))
    db = dot(n, sub(b, t0))
    return _seg_tri(a, b, da, db, t0, t1, t2, n)


@njit(**JIT)
def tri_tri_intersect(p0, p1, p2, q0, q1, q2):
    """Do the closed triangles p and q (3-tuples of 3-tuples of floats) meet?"""
    n_p = cross(sub(p1, p0), sub(p2, p0))
    n_q = cross(sub(q1, q0), sub(q2, q0))
    deg_p = _degenerate(p0, p1, p2, n_p)
    deg_q = _degenerate(q0, q1, q2, n_q)
    if deg_p or deg_q:
        if deg_p and deg_q:
            a, b = _longest_edge(p0, p1, p2)
            c, d = _longest_edge(q0, q1, q2)
            return _seg_seg_touch(a, b, c, d)
        if deg_p:
            a, b = _longest_edge(p0, p1, p2)
            return _seg_vs_tri(a, b, q0, q1, q2, n_q)
        a, b = _longest_edge(q0, q1, q2)
        return _seg_vs_tri(a, b, p0, p1, p2, n_p)

    d0 = dot(n_q, sub(p0, q0))
    d1 = dot(n_q, sub(p1, q0))
    d2 = dot(n_q, sub(p2, q0))
    if (d0 > 0 and d1 > 0 and d2 > 0) or (d0 < 0 and d1 < 0 and d2 < 0):
        return False
    e0 = dot(n_p, sub(q0, p0))
    e1 = dot(n_p, sub(q1, p0))
    e2 = dot(n_p, sub(q2, p0))
    if (e0 > 0 and e1 > 0 and e2 > 0) or (e0 < 0 and e1 < 0 and e2 < 0):
        return False
    if d0 == 0 and d1 == 0 and d2 == 0:
        return _coplanar_tri_tri(p0, p1, p2, q0, q1, q2, n_q)
    if e0 == 0 and e1 == 0 and e2 == 0:
        return _coplanar_tri_tri(p0, p1, p2, q0, q1, q2, n_p)
    if _seg_tri(p0, p1, d0, d1, q0, q1, q2, n_q):
        return True
    if _seg_tri(p1, p2, d1, d2, q0, q1, q2, n_q):
        return True
    if _seg_tri(p2, p0, d2, d0, q0, q1, q2, n_q):
        return True
    if _seg_tri(q0, q1, e0, e1, p0, p1, p2, n_p):
        return True
    if _seg_tri(q1, q2, e1, e2, p0, p1, p2, n_p):
        return True
    return _seg_tri(q2, q0, e2, e0, p0, p1, p2, n_p)


@njit(**JIT)
def plane_gap(p0, p1, p2, q0, q1, q2):
    """A cheap lower bound on the distance between two triangles: how far one lies wholly on
    one side of the other's plane (0 if neither plane separates them)."""
    best = 0.0
    n_q = cross(sub(q1, q0), sub(q2, q0))
    l = math.sqrt(norm2(n_q))
    if l > 0.0:
        d0 = dot(n_q, sub(p0, q0))
        d1 = dot(n_q, sub(p1, q0))
        d2 = dot(n_q, sub(p2, q0))
        if d0 > 0 and d1 > 0 and d2 > 0:
            best = max(best, min(d0, d1, d2) / l)
        elif d0 < 0 and d1 < 0 and d2 < 0:
            best = max(best, -max(d0, d1, d2) / l)
    n_p = cross(sub(p1, p0), sub(p2, p0))
    l = math.sqrt(norm2(n_p))
    if l > 0.0:
        e0 = dot(n_p, sub(q0, p0))
        e1 = dot(n_p, sub(q1, p0))
        e2 = dot(n_p, sub(q2, p0))
        if e0 > 0 and e1 > 0 and e2 > 0:
            best = max(best, min(e0, e1, e2) / l)
        elif e0 < 0 and e1 < 0 and e2 < 0:
            best = max(best, -max(e0, e1, e2) / l)
    return best


def _tup(v) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def tri_tri_intersect_np(p: np.ndarray, q: np.ndarray) -> bool:
    """``tri_tri_intersect`` on two ``(3, 3)`` arrays (rows are vertices)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    return bool(tri_tri_intersect(_tup(p[0]), _tup(p[1]), _tup(p[2]), _tup(q[0]), _tup(q[1]), _tup(q[2])))
