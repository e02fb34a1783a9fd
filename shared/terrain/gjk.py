"""Exact distance between one convex link shape and one triangle, with witness points (numba).

Shapes (``kind``): 0 sphere, 1 capsule, 2 cylinder, 3 box, posed by ``R`` (3, 3) and ``t`` (3,);
``par`` = (radius, half length along the shape's z, half x, half y, half z). A sphere or capsule
is its core (a point or a segment) grown by its radius: GJK runs on the core, which is a
polytope, so it ends exactly after a few steps, and the radius is taken off afterwards (this also
gives the penetration depth of a capsule). A box is a polytope too; a cylinder is the one curved
support, where GJK stops once its lower and upper bounds are within ``GJK_TOL``.

GJK (Gilbert, Johnson, Keerthi) with the closest point of each simplex found by region tests
(Ericson, Real-Time Collision Detection, ch. 5).
"""

from __future__ import annotations

import numba
import numpy as np

SPHERE, CAPSULE, CYLINDER, BOX = 0, 1, 2, 3
KIND_CODES = {"sphere": SPHERE, "capsule": CAPSULE, "cylinder": CYLINDER, "box": BOX}
#: stop when the distance is bracketed to within this (m)
GJK_TOL = 1e-9
GJK_MAX_ITER = 64


@numba.njit(cache=True, inline="always")
def _dot(a0, a1, a2, b0, b1, b2):
    return a0 * b0 + a1 * b1 + a2 * b2


@numba.njit(cache=True)
def shape_support(kind, R, t, par, d, out):
    """Support point of the shape's core (capsule/sphere: without radius) in direction d."""
    l0 = R[0, 0] * d[0] + R[1, 0] * d[1] + R[2, 0] * d[2]
    l1 = R[0, 1] * d[0] + R[1, 1] * d[1] + R[2, 1] * d[2]
    l2 = R[0, 2] * d[0] + R[1, 2] * d[1] + R[2, 2] * d[2]
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    if kind == CAPSULE:
        s2 = par[1] if l2 >= 0.0 else -par[1]
    elif kind == CYLINDER:
        w = np.sqrt(l0 * l0 + l1 * l1)
        if w > 1e-300:
            s0 = par[0] * l0 / w
            s1 = par[0] * l1 / w
        s2 = par[1] if l2 >= 0.0 else -par[1]
    elif kind == BOX:
        s0 = par[2] if l0 >= 0.0 else -par[2]
        s1 = par[3] if l1 >= 0.0 else -par[3]
        s2 = par[4] if l2 >= 0.0 else -par[4]
    for i in range(3):
        out[i] = t[i] + R[i, 0] * s0 + R[i, 1] * s1 + R[i, 2] * s2


@numba.njit(cache=True)
def _closest_on_triangle(a, b, c, lam):
    """Barycentric weights (into lam[0:3]) of the point of triangle abc closest to the origin."""
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    d1 = -_dot(ab0, ab1, ab2, a[0], a[1], a[2])
    d2 = -_dot(ac0, ac1, ac2, a[0], a[1], a[2])
    if d1 <= 0.0 and d2 <= 0.0:
        lam[0], lam[1], lam[2] = 1.0, 0.0, 0.0
        return
    d3 = -_dot(ab0, ab1, ab2, b[0], b[1], b[2])
    d4 = -_dot(ac0, ac1, ac2, b[0], b[1], b[2])
    if d3 >= 0.0 and d4 <= d3:
        lam[0], lam[1], lam[2] = 0.0, 1.0, 0.0
        return
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        lam[0], lam[1], lam[2] = 1.0 - v, v, 0.0
        return
    d5 = -_dot(ab0, ab1, ab2, c[0], c[1], c[2])
    d6 = -_dot(ac0, ac1, ac2, c[0], c[1], c[2])
    if d6 >= 0.0 and d5 <= d6:
        lam[0], lam[1], lam[2] = 0.0, 0.0, 1.0
        return
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        lam[0], lam[1], lam[2] = 1.0 - w, 0.0, w
        return
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        lam[0], lam[1], lam[2] = 0.0, 1.0 - w, w
        return
    denom = va + vb + vc
    if denom <= 0.0:  # degenerate triangle: fall back to its longest edge's end
        lam[0], lam[1], lam[2] = 1.0, 0.0, 0.0
        return
    v = vb / denom
    w = vc / denom
    lam[0], lam[1], lam[2] = 1.0 - v - w, v, w


@numba.njit(cache=True)
def _solve_simplex(W, A, B, n, lam, tmp3, tmpW, best_lam):
    """Replace the simplex (first n rows of W, A, B) by the smallest sub-simplex holding the
    point closest to the origin; weights in lam. Returns the new n (4 = origin enclosed)."""
    if n == 1:
        lam[0] = 1.0
        return 1
    if n == 2:
        e0, e1, e2 = W[1, 0] - W[0, 0], W[1, 1] - W[0, 1], W[1, 2] - W[0, 2]
        ee = e0 * e0 + e1 * e1 + e2 * e2
        s = 0.0
        if ee > 0.0:
            s = -_dot(W[0, 0], W[0, 1], W[0, 2], e0, e1, e2) / ee
        if s <= 0.0:
            lam[0] = 1.0
            return 1
        if s >= 1.0:
            for k in range(3):
                W[0, k] = W[1, k]
                A[0, k] = A[1, k]
                B[0, k] = B[1, k]
            lam[0] = 1.0
            return 1
        lam[0] = 1.0 - s
        lam[1] = s
        return 2
    if n == 3:
        _closest_on_triangle(W[0], W[1], W[2], tmp3)
        m = 0
        for i in range(3):
            if tmp3[i] > 0.0:
                for k in range(3):
                    W[m, k] = W[i, k]
                    A[m, k] = A[i, k]
                    B[m, k] = B[i, k]
                lam[m] = tmp3[i]
                m += 1
        return m
    # tetrahedron: origin inside, or closest on one of the faces the origin sees
    best = 1e300
    best_face = -1
    for f in range(4):
        if f == 0:
            i, j, k, o = 0, 1, 2, 3
        elif f == 1:
            i, j, k, o = 0, 1, 3, 2
        elif f == 2:
            i, j, k, o = 0, 2, 3, 1
        else:
            i, j, k, o = 1, 2, 3, 0
        u0, u1, u2 = W[j, 0] - W[i, 0], W[j, 1] - W[i, 1], W[j, 2] - W[i, 2]
        v0, v1, v2 = W[k, 0] - W[i, 0], W[k, 1] - W[i, 1], W[k, 2] - W[i, 2]
        n0, n1, n2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
        side_o = _dot(n0, n1, n2, W[o, 0] - W[i, 0], W[o, 1] - W[i, 1], W[o, 2] - W[i, 2])
        side_p = _dot(n0, n1, n2, -W[i, 0], -W[i, 1], -W[i, 2])
        if side_o * side_p < 0.0:  # origin beyond this face
            _closest_on_triangle(W[i], W[j], W[k], tmp3)
            p0 = tmp3[0] * W[i, 0] + tmp3[1] * W[j, 0] + tmp3[2] * W[k, 0]
            p1 = tmp3[0] * W[i, 1] + tmp3[1] * W[j, 1] + tmp3[2] * W[k, 1]
            p2 = tmp3[0] * W[i, 2] + tmp3[1] * W[j, 2] + tmp3[2] * W[k, 2]
            dd = p0 * p0 + p1 * p1 + p2 * p2
            if dd < best:
                best = dd
                best_face = f
                best_lam[0], best_lam[1], best_lam[2] = tmp3[0], tmp3[1], tmp3[2]
    if best_face < 0:
        return 4
    drop = 3 - best_face  # faces 0..3 leave out vertex 3, 2, 1, 0
    m = 0
    q = 0
    for src in range(4):
        if src == drop:
            continue
        if best_lam[q] > 0.0:
            for r in range(3):
                tmpW[0, m, r] = W[src, r]
                tmpW[1, m, r] = A[src, r]
                tmpW[2, m, r] = B[src, r]
            lam[m] = best_lam[q]
            m += 1
        q += 1
    for q in range(m):
        for r in range(3):
            W[q, r] = tmpW[0, q, r]
            A[q, r] = tmpW[1, q, r]
            B[q, r] = tmpW[2, q, r]
    return m


@numba.njit(cache=True)
def make_workspace():
    """Scratch memory for ``shape_triangle_distance`` (allocate once per query, not per call)."""
    return np.empty((32, 3))


@numba.njit(cache=True)
def shape_triangle_distance(kind, R, t, par, tri, pa, pb, upper, ws):
    """Distance from the shape to triangle ``tri`` (3, 3); witness points into pa (shape) and pb
    (triangle). Negative for a capsule or sphere whose core is within its radius (depth); 0 for
    an overlapping box or cylinder. Once GJK's lower bound passes ``upper`` (the best distance a
    caller already has) it stops and returns that bound, which is then > ``upper``."""
    grow = par[0] if (kind == SPHERE or kind == CAPSULE) else 0.0
    W = ws[0:4]
    A = ws[4:8]
    Bm = ws[8:12]
    tmpW = ws[12:24].reshape((3, 4, 3))
    d = ws[24]
    sa = ws[25]
    v = ws[26]
    tmp3 = ws[27]
    best_lam = ws[28]
    lam = ws[29:31].reshape(6)
    for k in range(3):
        v[k] = t[k] - (tri[0, k] + tri[1, k] + tri[2, k]) / 3.0
    if v[0] * v[0] + v[1] * v[1] + v[2] * v[2] < 1e-24:
        v[0] = 1.0
    n = 0
    inside = False
    for it in range(GJK_MAX_ITER):
        for k in range(3):
            d[k] = -v[k]
        shape_support(kind, R, t, par, d, sa)
        # triangle support in -d = v
        best_i = 0
        best_s = _dot(tri[0, 0], tri[0, 1], tri[0, 2], v[0], v[1], v[2])
        for i in range(1, 3):
            s = _dot(tri[i, 0], tri[i, 1], tri[i, 2], v[0], v[1], v[2])
            if s > best_s:
                best_s = s
                best_i = i
        w0 = sa[0] - tri[best_i, 0]
        w1 = sa[1] - tri[best_i, 1]
        w2 = sa[2] - tri[best_i, 2]
        if n > 0:
            vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
            vw = v[0] * w0 + v[1] * w1 + v[2] * w2
            nv = np.sqrt(vv)
            if vv - vw <= GJK_TOL * nv:
                break
            if vw > 0.0 and vw / nv - grow > upper:
                return vw / nv - grow
            dup = False
            for i in range(n):
                if W[i, 0] == w0 and W[i, 1] == w1 and W[i, 2] == w2:
                    dup = True
            if dup:
                break
        W[n, 0], W[n, 1], W[n, 2] = w0, w1, w2
        for k in range(3):
            A[n, k] = sa[k]
            Bm[n, k] = tri[best_i, k]
        n += 1
        n = _solve_simplex(W, A, Bm, n, lam, tmp3, tmpW, best_lam)
        if n == 4:
            inside = True
            break
        for k in range(3):
            v[k] = 0.0
            for i in range(n):
                v[k] += lam[i] * W[i, k]
        if v[0] * v[0] + v[1] * v[1] + v[2] * v[2] < 1e-28:
            inside = True
            break
    for k in range(3):
        pa[k] = 0.0
        pb[k] = 0.0
        for i in range(n if n < 4 else 0):
            pa[k] += lam[i] * A[i, k]
            pb[k] += lam[i] * Bm[i, k]
    if inside:
        if n == 4:
            for k in range(3):
                pa[k] = A[0, k]
                pb[k] = A[0, k]
        dist = 0.0
    else:
        dist = np.sqrt((pa[0] - pb[0]) ** 2 + (pa[1] - pb[1]) ** 2 + (pa[2] - pb[2]) ** 2)
    if kind == SPHERE or kind == CAPSULE:
        r = par[0]
        if dist > 0.0:
            for k in range(3):
                pa[k] += r * (pb[k] - pa[k]) / dist
        return dist - r
    return dist
