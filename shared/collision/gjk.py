"""Exact distance between two convex polyhedra given by their vertices (GJK), compiled.

Gilbert-Johnson-Keerthi on the Minkowski difference ``A - B``: keep a simplex of at most four
support points ``w = a - b`` and move ``v``, the simplex's point nearest the origin, until the
support in direction ``-v`` brings nothing nearer. On polyhedra it ends after finitely many
steps with ``|v|`` the exact distance and the witness points the same convex combination of the
simplex's ``a`` and ``b`` (van den Bergen, *Collision Detection in Interactive 3D
Environments*, ch. 4; the simplex's nearest point by Voronoi regions as in Ericson, *Real-Time
Collision Detection*, 5.1.5 and 5.1.6).

Support queries climb the hull's edge graph from the last support vertex (a vertex no neighbour
of which lies further along a direction is the furthest of the whole polyhedron), so a query
costs a few dot products however many vertices a tessellated capsule has.

Body ``b``'s vertices are mapped into body ``a``'s frame by ``R``, ``t``; all points returned
are in ``a``'s frame. Each call answers one of: ``APART`` (the distance and witness points),
``PRUNED`` (the distance is at least ``upper``: GJK's lower bound ``v.w / |v|`` reached it) or
``OVERLAP`` (the solids meet or GJK did not converge: the caller falls back to the triangles).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from shared.collision.tri_tri import JIT

APART = 0
PRUNED = 1
OVERLAP = 2

#: iterations before giving up (a polyhedron pair ends in far fewer)
MAX_ITERATIONS = 128
#: stop when |v|^2 - v.w, an upper bound on |v| (|v| - distance), falls below this times |v|^2
#: or ``ABS_GAP`` (m) times |v|: the distance is then within that of the exact one
REL_GAP = 1e-14
ABS_GAP = 1e-13
#: squared distances below this (m^2) count as touching: the triangles decide
TOUCH2 = 1e-26
#: at or below this many vertices a support query scans them all
SCAN = 16


@njit(**JIT)
def support(V, adj_start, adj, start, count, first, d0, d1, d2):
    """Index of a vertex of the polyhedron ``start .. start + count`` of ``V`` furthest along
    ``d``, climbing the edge graph from ``first``."""
    if count <= SCAN:
        best = start
        bv = V[start, 0] * d0 + V[start, 1] * d1 + V[start, 2] * d2
        for u in range(start + 1, start + count):
            val = V[u, 0] * d0 + V[u, 1] * d1 + V[u, 2] * d2
            if val > bv:
                bv = val
                best = u
        return best
    best = first
    bv = V[best, 0] * d0 + V[best, 1] * d1 + V[best, 2] * d2
    while True:
        nxt = best
        for e in range(adj_start[best], adj_start[best + 1]):
            u = adj[e]
            val = V[u, 0] * d0 + V[u, 1] * d1 + V[u, 2] * d2
            if val > bv:
                bv = val
                nxt = u
        if nxt == best:
            return best
        best = nxt


@njit(**JIT)
def _copy_row(S, dst, src):
    for k in range(9):
        S[dst, k] = S[src, k]


@njit(**JIT)
def _keep(S, SI, lam, n, l0, l1, l2, l3):
    """Compact the simplex to the points with a positive weight; return its new size."""
    lam[0] = l0
    lam[1] = l1
    lam[2] = l2
    lam[3] = l3
    m = 0
    for k in range(n):
        if lam[k] > 0.0:
            if m != k:
                _copy_row(S, m, k)
                SI[m, 0] = SI[k, 0]
                SI[m, 1] = SI[k, 1]
                lam[m] = lam[k]
            m += 1
    return m


@njit(**JIT)
def _dot(S, i, j):
    return S[i, 0] * S[j, 0] + S[i, 1] * S[j, 1] + S[i, 2] * S[j, 2]


@njit(**JIT)
def _triangle(S, i, j, k):
    """Barycentric weights (on points i, j, k of S's w columns) of the triangle's point nearest
    the origin (Ericson 5.1.5 with p = 0)."""
    ab0 = S[j, 0] - S[i, 0]
    ab1 = S[j, 1] - S[i, 1]
    ab2 = S[j, 2] - S[i, 2]
    ac0 = S[k, 0] - S[i, 0]
    ac1 = S[k, 1] - S[i, 1]
    ac2 = S[k, 2] - S[i, 2]
    d1 = -(ab0 * S[i, 0] + ab1 * S[i, 1] + ab2 * S[i, 2])
    d2 = -(ac0 * S[i, 0] + ac1 * S[i, 1] + ac2 * S[i, 2])
    if d1 <= 0.0 and d2 <= 0.0:
        return 1.0, 0.0, 0.0
    d3 = -(ab0 * S[j, 0] + ab1 * S[j, 1] + ab2 * S[j, 2])
    d4 = -(ac0 * S[j, 0] + ac1 * S[j, 1] + ac2 * S[j, 2])
    if d3 >= 0.0 and d4 <= d3:
        return 0.0, 1.0, 0.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return 1.0 - v, v, 0.0
    d5 = -(ab0 * S[k, 0] + ab1 * S[k, 1] + ab2 * S[k, 2])
    d6 = -(ac0 * S[k, 0] + ac1 * S[k, 1] + ac2 * S[k, 2])
    if d6 >= 0.0 and d5 <= d6:
        return 0.0, 0.0, 1.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return 1.0 - w, 0.0, w
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return 0.0, 1.0 - w, w
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return 1.0 - v - w, v, w


@njit(**JIT)
def _point2(S, l0, l1, l2, l3, n):
    """|sum lam_k w_k|^2 over the first n points."""
    x = 0.0
    y = 0.0
    z = 0.0
    lam = (l0, l1, l2, l3)
    for k in range(n):
        x += lam[k] * S[k, 0]
        y += lam[k] * S[k, 1]
        z += lam[k] * S[k, 2]
    return x * x + y * y + z * z


@njit(**JIT)
def _outside(S, i, j, k, m):
    """Is the origin on the other side of plane (i, j, k) from point m (or the simplex flat)?"""
    ab0 = S[j, 0] - S[i, 0]
    ab1 = S[j, 1] - S[i, 1]
    ab2 = S[j, 2] - S[i, 2]
    ac0 = S[k, 0] - S[i, 0]
    ac1 = S[k, 1] - S[i, 1]
    ac2 = S[k, 2] - S[i, 2]
    n0 = ab1 * ac2 - ab2 * ac1
    n1 = ab2 * ac0 - ab0 * ac2
    n2 = ab0 * ac1 - ab1 * ac0
    sp = -(n0 * S[i, 0] + n1 * S[i, 1] + n2 * S[i, 2])
    sd = n0 * (S[m, 0] - S[i, 0]) + n1 * (S[m, 1] - S[i, 1]) + n2 * (S[m, 2] - S[i, 2])
    return sp * sd <= 0.0


@njit(**JIT)
def _nearest(S, SI, lam, n):
    """Reduce the simplex (n points in S's rows: w, a, b) to the smallest one holding its point
    nearest the origin, with weights in ``lam``; return its size (4: the origin is inside)."""
    if n == 1:
        lam[0] = 1.0
        return 1
    if n == 2:
        ab0 = S[1, 0] - S[0, 0]
        ab1 = S[1, 1] - S[0, 1]
        ab2 = S[1, 2] - S[0, 2]
        ll = ab0 * ab0 + ab1 * ab1 + ab2 * ab2
        tt = -(ab0 * S[0, 0] + ab1 * S[0, 1] + ab2 * S[0, 2])
        if ll <= 0.0 or tt <= 0.0:
            return _keep(S, SI, lam, 2, 1.0, 0.0, 0.0, 0.0)
        if tt >= ll:
            return _keep(S, SI, lam, 2, 0.0, 1.0, 0.0, 0.0)
        s = tt / ll
        return _keep(S, SI, lam, 2, 1.0 - s, s, 0.0, 0.0)
    if n == 3:
        l0, l1, l2 = _triangle(S, 0, 1, 2)
        return _keep(S, SI, lam, 3, l0, l1, l2, 0.0)
    # tetrahedron: the nearest point over the faces the origin lies outside of
    best = np.inf
    b0 = b1 = b2 = b3 = 0.0
    inside = True
    if _outside(S, 0, 1, 2, 3):
        inside = False
        l0, l1, l2 = _triangle(S, 0, 1, 2)
        d = _point2(S, l0, l1, l2, 0.0, 4)
        if d < best:
            best, b0, b1, b2, b3 = d, l0, l1, l2, 0.0
    if _outside(S, 0, 2, 3, 1):
        inside = False
        l0, l2, l3 = _triangle(S, 0, 2, 3)
        d = _point2(S, l0, 0.0, l2, l3, 4)
        if d < best:
            best, b0, b1, b2, b3 = d, l0, 0.0, l2, l3
    if _outside(S, 0, 3, 1, 2):
        inside = False
        l0, l3, l1 = _triangle(S, 0, 3, 1)
        d = _point2(S, l0, l1, 0.0, l3, 4)
        if d < best:
            best, b0, b1, b2, b3 = d, l0, l1, 0.0, l3
    if _outside(S, 1, 3, 2, 0):
        inside = False
        l1, l3, l2 = _triangle(S, 1, 3, 2)
        d = _point2(S, 0.0, l1, l2, l3, 4)
        if d < best:
            best, b0, b1, b2, b3 = d, 0.0, l1, l2, l3
    if inside:
        return 4
    return _keep(S, SI, lam, 4, b0, b1, b2, b3)


@njit(**JIT)
def gjk_distance(V, adj_start, adj, sa, na, sb, nb, R, t, upper, S, SI, lam, hint):
    """Distance between polyhedra A (rows ``sa .. sa + na`` of ``V``) and B (``sb .. sb + nb``,
    mapped by ``R``, ``t`` into A's frame), looked for below ``upper``.

    ``S`` (8, 9), ``SI`` (8, 2), ``lam`` (8,): scratch (rows 4-7 keep the last simplex). ``hint`` (3,): a direction from A
    towards B to start along. Returns ``(status, distance, point on A, point on B)``.
    """
    nan3 = (np.nan, np.nan, np.nan)
    # first support pair along the hint
    ia = support(V, adj_start, adj, sa, na, sa, hint[0], hint[1], hint[2])
    e0 = -(R[0, 0] * hint[0] + R[1, 0] * hint[1] + R[2, 0] * hint[2])
    e1 = -(R[0, 1] * hint[0] + R[1, 1] * hint[1] + R[2, 1] * hint[2])
    e2 = -(R[0, 2] * hint[0] + R[1, 2] * hint[1] + R[2, 2] * hint[2])
    ib = support(V, adj_start, adj, sb, nb, sb, e0, e1, e2)
    n = 0
    last_a = ia
    last_b = ib
    v0 = v1 = v2 = 0.0
    vv = np.inf
    upper2 = upper * upper
    for it in range(MAX_ITERATIONS):
        if it > 0:
            ia = support(V, adj_start, adj, sa, na, last_a, -v0, -v1, -v2)
            e0 = R[0, 0] * v0 + R[1, 0] * v1 + R[2, 0] * v2
            e1 = R[0, 1] * v0 + R[1, 1] * v1 + R[2, 1] * v2
            e2 = R[0, 2] * v0 + R[1, 2] * v1 + R[2, 2] * v2
            ib = support(V, adj_start, adj, sb, nb, last_b, e0, e1, e2)
            last_a = ia
            last_b = ib
        a0 = V[ia, 0]
        a1 = V[ia, 1]
        a2 = V[ia, 2]
        b0 = R[0, 0] * V[ib, 0] + R[0, 1] * V[ib, 1] + R[0, 2] * V[ib, 2] + t[0]
        b1 = R[1, 0] * V[ib, 0] + R[1, 1] * V[ib, 1] + R[1, 2] * V[ib, 2] + t[1]
        b2 = R[2, 0] * V[ib, 0] + R[2, 1] * V[ib, 1] + R[2, 2] * V[ib, 2] + t[2]
        w0 = a0 - b0
        w1 = a1 - b1
        w2 = a2 - b2
        if it > 0:
            vw = v0 * w0 + v1 * w1 + v2 * w2
            if vw > 0.0 and vw * vw >= upper2 * vv:
                return PRUNED, math.sqrt(vv), nan3, nan3
            if vv - vw <= REL_GAP * vv or vv - vw <= ABS_GAP * math.sqrt(vv):
                break
            dup = False
            for k in range(n):
                if SI[k, 0] == ia and SI[k, 1] == ib:
                    dup = True
            if dup:
                break
        for k in range(n):  # keep the simplex: a step that brings nothing nearer is undone
            for c in range(9):
                S[4 + k, c] = S[k, c]
            SI[4 + k, 0] = SI[k, 0]
            SI[4 + k, 1] = SI[k, 1]
            lam[4 + k] = lam[k]
        n_prev = n
        S[n, 0] = w0
        S[n, 1] = w1
        S[n, 2] = w2
        S[n, 3] = a0
        S[n, 4] = a1
        S[n, 5] = a2
        S[n, 6] = b0
        S[n, 7] = b1
        S[n, 8] = b2
        SI[n, 0] = ia
        SI[n, 1] = ib
        n = _nearest(S, SI, lam, n + 1)
        if n == 4:
            return OVERLAP, 0.0, nan3, nan3
        v0 = v1 = v2 = 0.0
        for k in range(n):
            v0 += lam[k] * S[k, 0]
            v1 += lam[k] * S[k, 1]
            v2 += lam[k] * S[k, 2]
        vv_new = v0 * v0 + v1 * v1 + v2 * v2
        if vv_new <= TOUCH2:
            return OVERLAP, 0.0, nan3, nan3
        if vv_new >= vv:  # rounding: the previous simplex stands
            n = n_prev
            for k in range(n):
                for c in range(9):
                    S[k, c] = S[4 + k, c]
                lam[k] = lam[4 + k]
            break
        vv = vv_new
    else:
        return OVERLAP, 0.0, nan3, nan3
    p0 = p1 = p2 = q0 = q1 = q2 = 0.0
    for k in range(n):
        p0 += lam[k] * S[k, 3]
        p1 += lam[k] * S[k, 4]
        p2 += lam[k] * S[k, 5]
        q0 += lam[k] * S[k, 6]
        q1 += lam[k] * S[k, 7]
        q2 += lam[k] * S[k, 8]
    return APART, math.sqrt(vv), (p0, p1, p2), (q0, q1, q2)
