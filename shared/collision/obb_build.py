"""The OBB tree's top-down build (``shared.collision.obb_tree``) compiled with numba.

The same algorithm as the Python reference in ``obb_tree`` (``fit_obb``, ``_split``), node by
node in preorder: a node's box is the smallest of the covariance basis, the body axes and the
frames of its largest triangle; it splits by the vertex mean along its longest axis (then the
others), each triangle to the side of its centroid. Triangle ids are partitioned in place, so a
node is a range of one permutation, and leaves come out in preorder as the reference places
them. In Python a node cost about half a millisecond (numpy's per-call overhead on tiny arrays):
a robot's link meshes took five seconds at every process start; compiled they take a few tens
of milliseconds.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shared.collision.tri_tri import JIT


@njit(**JIT)
def _covariance_basis(tris, areas, perm, lo, hi):
    """Gottschalk's area-weighted covariance of the node's triangles: its eigenvectors as
    columns, right-handed (``obb_tree.covariance_axes``)."""
    total = 0.0
    for k in range(lo, hi):
        total += areas[perm[k]]
    cov = np.zeros((3, 3))
    if total <= 0.0:  # all slivers: plain vertex covariance
        n = 3 * (hi - lo)
        if n > 1:
            mean = np.zeros(3)
            for k in range(lo, hi):
                for c in range(3):
                    for i in range(3):
                        mean[i] += tris[perm[k], c, i]
            mean /= n
            for k in range(lo, hi):
                for c in range(3):
                    for i in range(3):
                        for j in range(3):
                            cov[i, j] += (tris[perm[k], c, i] - mean[i]) * (tris[perm[k], c, j] - mean[j])
            cov /= n
    else:
        m_h = np.zeros(3)
        s = np.zeros((3, 3))
        for k in range(lo, hi):
            t = perm[k]
            a = areas[t]
            m = (tris[t, 0] + tris[t, 1] + tris[t, 2]) / 3.0
            for i in range(3):
                m_h[i] += a * m[i]
                for j in range(3):
                    s[i, j] += a * (9.0 * m[i] * m[j] + tris[t, 0, i] * tris[t, 0, j]
                                    + tris[t, 1, i] * tris[t, 1, j] + tris[t, 2, i] * tris[t, 2, j])
        m_h /= total
        for i in range(3):
            for j in range(3):
                cov[i, j] = s[i, j] / (12.0 * total) - m_h[i] * m_h[j]
    _, v = np.linalg.eigh(0.5 * (cov + cov.T))
    v = np.ascontiguousarray(v)
    if np.linalg.det(v) < 0:
        v[:, 2] = -v[:, 2]
    return v


@njit(**JIT)
def _box(tris, perm, lo, hi, basis):
    """Centre and half extents of the node's vertices in ``basis`` (columns)."""
    mn = np.full(3, np.inf)
    mx = np.full(3, -np.inf)
    for k in range(lo, hi):
        t = perm[k]
        for c in range(3):
            for a in range(3):
                p = tris[t, c, 0] * basis[0, a] + tris[t, c, 1] * basis[1, a] + tris[t, c, 2] * basis[2, a]
                if p < mn[a]:
                    mn[a] = p
                if p > mx[a]:
                    mx[a] = p
    mid = (mn + mx) / 2.0
    return basis @ mid, (mx - mn) / 2.0


@njit(**JIT)
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(**JIT)
def _fit(tris, areas, perm, lo, hi, pad):
    """``obb_tree.fit_obb`` of the node's triangles: (centre, axes as columns, half + pad)."""
    bases = np.zeros((5, 3, 3))
    bases[0] = _covariance_basis(tris, areas, perm, lo, hi)
    bases[1] = np.eye(3)
    n_bases = 2
    big = perm[lo]
    for k in range(lo + 1, hi):  # the largest triangle (the first of equals, as np.argmax)
        if areas[perm[k]] > areas[big]:
            big = perm[k]
    p0, p1, p2 = tris[big, 0], tris[big, 1], tris[big, 2]
    edges = (p1 - p0, p2 - p1, p0 - p2)
    n = _cross(p1 - p0, p2 - p0)
    ln = np.sqrt(n @ n)
    if ln > 0.0:
        z = n / ln
        for e in edges:
            le = np.sqrt(e @ e)
            if le > 0.0:
                x = e / le
                y = _cross(z, x)
                for i in range(3):
                    bases[n_bases, i, 0] = x[i]
                    bases[n_bases, i, 1] = y[i]
                    bases[n_bases, i, 2] = z[i]
                n_bases += 1
    best_score = np.inf
    best_center = np.zeros(3)
    best_half = np.zeros(3)
    best_basis = bases[0].copy()
    found = False
    for b in range(n_bases):
        center, half = _box(tris, perm, lo, hi, bases[b])
        eps = 1e-6 * max(half.max(), 1e-12)
        score = (half[0] + eps) * (half[1] + eps) * (half[2] + eps)
        if not found or score < best_score * (1.0 - 1e-9):
            found = True
            best_score, best_center, best_half, best_basis = score, center, half, bases[b].copy()
    return best_center, best_basis, best_half + pad


@njit(**JIT)
def _split(tris, perm, lo, hi, axes, half, scratch):
    """Partition ``perm[lo:hi]`` (stably) by the vertex-mean plane across the longest axis that
    leaves both sides non-empty; the left side's size, or -1 when no axis does."""
    count = hi - lo
    mean = np.zeros(3)
    for k in range(lo, hi):
        for c in range(3):
            mean += tris[perm[k], c]
    mean /= 3 * count
    order = np.argsort(-half, kind="mergesort")
    side = np.empty(count, dtype=np.bool_)
    for a in order:
        ax0, ax1, ax2 = axes[0, a], axes[1, a], axes[2, a]
        n_left = 0
        for k in range(lo, hi):
            t = perm[k]
            d0 = (tris[t, 0, 0] + tris[t, 1, 0] + tris[t, 2, 0]) / 3.0 - mean[0]
            d1 = (tris[t, 0, 1] + tris[t, 1, 1] + tris[t, 2, 1]) / 3.0 - mean[1]
            d2 = (tris[t, 0, 2] + tris[t, 1, 2] + tris[t, 2, 2]) / 3.0 - mean[2]
            side[k - lo] = d0 * ax0 + d1 * ax1 + d2 * ax2 < 0.0
            if side[k - lo]:
                n_left += 1
        if 0 < n_left < count:
            i_left, i_right = 0, n_left
            for k in range(lo, hi):
                t = perm[k]
                if side[k - lo]:
                    scratch[i_left] = t
                    i_left += 1
                else:
                    scratch[i_right] = t
                    i_right += 1
            perm[lo:hi] = scratch[:count]
            return n_left
    return -1


@njit(**JIT)
def build_nodes(tris, areas, leaf_size, pad):
    """The tree's node arrays in preorder and the triangle permutation (leaves' ranges)."""
    n_tris = tris.shape[0]
    cap = max(2 * n_tris - 1, 1)
    center = np.zeros((cap, 3))
    axes = np.zeros((cap, 3, 3))
    half = np.zeros((cap, 3))
    radius = np.zeros(cap)
    left = np.full(cap, -1, dtype=np.int64)
    right = np.full(cap, -1, dtype=np.int64)
    start = np.full(cap, -1, dtype=np.int64)
    count = np.zeros(cap, dtype=np.int64)
    perm = np.arange(n_tris).astype(np.int64)
    scratch = np.empty(n_tris, dtype=np.int64)
    # the stack of (lo, hi, parent, is_left)
    stack = np.zeros((cap + 1, 4), dtype=np.int64)
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = 0, n_tris, -1, 0
    top = 1
    n_nodes = 0
    while top > 0:
        top -= 1
        lo, hi, parent, is_left = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        node = n_nodes
        n_nodes += 1
        if parent >= 0:
            if is_left == 1:
                left[parent] = node
            else:
                right[parent] = node
        c, ax, h = _fit(tris, areas, perm, lo, hi, pad)
        center[node], axes[node], half[node] = c, ax, h
        r2 = 0.0
        for k in range(lo, hi):
            for v in range(3):
                d = tris[perm[k], v] - c
                r2 = max(r2, d @ d)
        radius[node] = np.sqrt(r2) + pad
        n_left = _split(tris, perm, lo, hi, ax, h, scratch) if hi - lo > leaf_size else -1
        if n_left < 0:
            start[node] = lo
            count[node] = hi - lo
        else:
            mid = lo + n_left
            # right pushed first so the left child is numbered next (preorder)
            stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = mid, hi, node, 0
            stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = lo, mid, node, 1
            top += 2
    return (center[:n_nodes], axes[:n_nodes], half[:n_nodes], radius[:n_nodes], left[:n_nodes], right[:n_nodes],
            start[:n_nodes], count[:n_nodes], perm)
