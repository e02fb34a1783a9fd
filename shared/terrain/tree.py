"""The multi-way AABB tree of seed 004 §3.2.2: every terrain triangle sits in a leaf, leaves hold
up to ``leaf_size`` triangles and inner nodes up to ``branching`` children.

Built bottom-up over a Morton (Z-order) sort of the triangle centres on the ground plane: leaves
are runs of consecutive triangles and each level groups runs of ``branching`` nodes, so a node's
children are implicit (``i * B ... i * B + B - 1`` on the next level) and the tree is only the
node boxes (about 3 MB beside 20 MB of vertices and triangles for 670k triangles with the
default 16-way, 8-per-leaf tree, chosen by the sweep in ``benchmarks/bench_terrain.py``). ``branching=2, leaf_size=1`` gives the classic binary AABB tree
for comparison.

Queries (numba): minimum distance from convex shapes (``shared.terrain.gjk``) with witness
points, best-first by box lower bound; nearest ray hit (the virtual sensors); all triangles
within a distance of a shape (contact triangles, local normals).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from shared.errors import InputError
from shared.terrain.gjk import make_workspace, shape_triangle_distance
from shared.terrain.triangulate import TerrainMesh

DEFAULT_BRANCHING = 16
DEFAULT_LEAF_SIZE = 8


@numba.njit(cache=True)
def _spread_bits(v):
    v = v & 0xFFFF
    v = (v | (v << 8)) & 0x00FF00FF
    v = (v | (v << 4)) & 0x0F0F0F0F
    v = (v | (v << 2)) & 0x33333333
    v = (v | (v << 1)) & 0x55555555
    return v


@numba.njit(cache=True)
def _morton_keys(vertices, faces):
    n = faces.shape[0]
    cx = np.empty(n)
    cy = np.empty(n)
    for i in range(n):
        cx[i] = (vertices[faces[i, 0], 0] + vertices[faces[i, 1], 0] + vertices[faces[i, 2], 0]) / 3.0
        cy[i] = (vertices[faces[i, 0], 1] + vertices[faces[i, 1], 1] + vertices[faces[i, 2], 1]) / 3.0
    x0, x1, y0, y1 = cx.min(), cx.max(), cy.min(), cy.max()
    sx = 65535.0 / max(x1 - x0, 1e-12)
    sy = 65535.0 / max(y1 - y0, 1e-12)
    keys = np.empty(n, np.int64)
    for i in range(n):
        keys[i] = (_spread_bits(np.int64((cx[i] - x0) * sx)) << 1) | _spread_bits(np.int64((cy[i] - y0) * sy))
    return keys


@numba.njit(cache=True)
def _leaf_boxes(vertices, faces, leaf_size, lo, hi):
    n = faces.shape[0]
    n_leaves = lo.shape[0]
    for j in range(n_leaves):
        for k in range(3):
            lo[j, k] = 1e300
            hi[j, k] = -1e300
        for f in range(j * leaf_size, min(n, (j + 1) * leaf_size)):
            for c in range(3):
                for k in range(3):
                    x = vertices[faces[f, c], k]
                    if x < lo[j, k]:
                        lo[j, k] = x
                    if x > hi[j, k]:
                        hi[j, k] = x


@numba.njit(cache=True)
def _parent_boxes(clo, chi, branching, lo, hi):
    nc = clo.shape[0]
    for i in range(lo.shape[0]):
        for k in range(3):
            lo[i, k] = 1e300
            hi[i, k] = -1e300
        for c in range(i * branching, min(nc, (i + 1) * branching)):
            for k in range(3):
                if clo[c, k] < lo[i, k]:
                    lo[i, k] = clo[c, k]
                if chi[c, k] > hi[i, k]:
                    hi[i, k] = chi[c, k]


@dataclass(frozen=True)
class TerrainTree:
    """Node boxes level by level (root first): ``lo``/``hi`` (n_nodes, 3), level ``k`` occupying
    rows ``starts[k] : starts[k] + counts[k]``; the last level is the leaves. ``faces`` are the
    triangles in tree order, ``face_ids`` their index in the input mesh."""

    vertices: np.ndarray
    faces: np.ndarray
    face_ids: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    starts: np.ndarray
    counts: np.ndarray
    branching: int
    leaf_size: int

    @property
    def depth(self) -> int:
        return int(len(self.counts))

    @property
    def n_triangles(self) -> int:
        return int(self.faces.shape[0])

    @property
    def nbytes(self) -> int:
        """Memory of the structure: vertices, triangles, ids and node boxes."""
        return int(sum(a.nbytes for a in (self.vertices, self.faces, self.face_ids, self.lo, self.hi, self.starts, self.counts)))

    def triangle(self, face_id: int) -> np.ndarray:
        """Corners (3, 3) of a triangle by its index in the input mesh."""
        pos = int(np.flatnonzero(self.face_ids == face_id)[0])
        return self.vertices[self.faces[pos]]

    def arrays(self) -> tuple:
        return (self.vertices, self.faces, self.lo, self.hi, self.starts, self.counts, self.branching, self.leaf_size)


def build_tree(mesh: TerrainMesh, branching: int = DEFAULT_BRANCHING, leaf_size: int = DEFAULT_LEAF_SIZE) -> TerrainTree:
    """Build the tree over a terrain mesh (once per terrain)."""
    if branching < 2 or leaf_size < 1:
        raise InputError(f"tree needs branching >= 2 and leaf size >= 1, got {branching} and {leaf_size}")
    if mesh.n_triangles == 0:
        raise InputError("cannot build a tree over a mesh without triangles")
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    faces_in = np.ascontiguousarray(mesh.faces, dtype=np.int32)
    order = np.argsort(_morton_keys(vertices, faces_in), kind="stable").astype(np.int32)
    faces = np.ascontiguousarray(faces_in[order])
    levels_lo = []
    levels_hi = []
    n = -(-len(faces) // leaf_size)
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    _leaf_boxes(vertices, faces, leaf_size, lo, hi)
    levels_lo.append(lo)
    levels_hi.append(hi)
    while n > 1:
        n = -(-n // branching)
        plo = np.empty((n, 3))
        phi = np.empty((n, 3))
        _parent_boxes(levels_lo[-1], levels_hi[-1], branching, plo, phi)
        levels_lo.append(plo)
        levels_hi.append(phi)
    levels_lo.reverse()
    levels_hi.reverse()
    counts = np.array([len(a) for a in levels_lo], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    return TerrainTree(vertices, faces, order, np.concatenate(levels_lo), np.concatenate(levels_hi), starts, counts,
                       int(branching), int(leaf_size))


# ------------------------------------------------------------------------------- queries


@numba.njit(cache=True, inline="always")
def _box_gap(alo, ahi, blo0, blo1, blo2, bhi0, bhi1, bhi2):
    """Squared distance between box a (arrays) and box b (scalars)."""
    s = 0.0
    g = blo0 - ahi[0]
    if g > 0.0:
        s += g * g
    g = alo[0] - bhi0
    if g > 0.0:
        s += g * g
    g = blo1 - ahi[1]
    if g > 0.0:
        s += g * g
    g = alo[1] - bhi1
    if g > 0.0:
        s += g * g
    g = blo2 - ahi[2]
    if g > 0.0:
        s += g * g
    g = alo[2] - bhi2
    if g > 0.0:
        s += g * g
    return s


#: most spheres used to bound one shape
MAX_SPHERES = 16


@numba.njit(cache=True)
def _bound(slo, shi, sph, n_sph, blo0, blo1, blo2, bhi0, bhi1, bhi2):
    """Lower bound on the distance from a shape to a box b: the larger of the gap between the
    shape's box and b and the smallest gap between b and the spheres that cover the shape
    (much tighter than the box alone for a long tilted link)."""
    d_box = np.sqrt(_box_gap(slo, shi, blo0, blo1, blo2, bhi0, bhi1, bhi2))
    d_sph = 1e300
    for i in range(n_sph):
        g0 = max(blo0 - sph[i, 0], 0.0, sph[i, 0] - bhi0)
        g1 = max(blo1 - sph[i, 1], 0.0, sph[i, 1] - bhi1)
        g2 = max(blo2 - sph[i, 2], 0.0, sph[i, 2] - bhi2)
        d = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2) - sph[i, 3]
        if d < d_sph:
            d_sph = d
            if d <= d_box:
                return d_box
    return max(d_box, d_sph)


@numba.njit(cache=True)
def _node_bound(slo, shi, sph, n_sph, lo, hi, row):
    return _bound(slo, shi, sph, n_sph, lo[row, 0], lo[row, 1], lo[row, 2], hi[row, 0], hi[row, 1], hi[row, 2])


@numba.njit(cache=True)
def shape_spheres(kind, R, t, par, sph):
    """Cover the shape with up to MAX_SPHERES spheres (rows x, y, z, radius) along its longest
    axis, about one cross-section radius apart; returns how many."""
    if kind == 3:
        ax = 0
        if par[3] > par[2 + ax]:
            ax = 1
        if par[4] > par[2 + ax]:
            ax = 2
        half = par[2 + ax]
        cross = 0.0
        for k in range(3):
            if k != ax:
                cross += par[2 + k] ** 2
        cross = np.sqrt(cross)
    else:
        ax = 2
        half = par[1]
        cross = par[0]
    n = int(np.ceil(2.0 * half / max(cross, 1e-9)))
    n = max(1, min(MAX_SPHERES, n))
    step = 2.0 * half / n
    if kind == 1 or kind == 0:  # capsule, sphere: the core segment grown by the radius
        rad = par[0] + 0.5 * step
    else:
        rad = np.sqrt(cross * cross + 0.25 * step * step)
    for i in range(n):
        s = -half + (i + 0.5) * step
        for k in range(3):
            sph[i, k] = t[k] + R[k, ax] * s
        sph[i, 3] = rad
    return n


@numba.njit(cache=True)
def shape_bounds(kind, R, t, par, slo, shi, sc):
    """World box (slo, shi) and bounding-sphere centre (sc) of a posed shape; returns the radius."""
    for i in range(3):
        if kind == 3:  # box
            e = abs(R[i, 0]) * par[2] + abs(R[i, 1]) * par[3] + abs(R[i, 2]) * par[4]
        elif kind == 2:  # cylinder: disc extent plus axis extent
            e = abs(R[i, 2]) * par[1] + par[0] * np.sqrt(max(0.0, 1.0 - R[i, 2] * R[i, 2]))
        else:  # capsule, sphere
            e = abs(R[i, 2]) * par[1] + par[0]
        slo[i] = t[i] - e
        shi[i] = t[i] + e
        sc[i] = t[i]
    if kind == 3:
        return np.sqrt(par[2] ** 2 + par[3] ** 2 + par[4] ** 2)
    if kind == 2:
        return np.sqrt(par[0] ** 2 + par[1] ** 2)
    return par[1] + par[0]


@numba.njit(cache=True)
def _cylinder_triangle(R, t, par, par_core, tri, pa, pb, upper, ws):
    """Cylinder to triangle through its axis first: every cylinder point is within the radius
    of the axis segment, so (segment distance - radius) bounds the distance from below, and it
    is the exact distance when the segment's nearest point is inside the segment (the nearest
    cylinder point is then on the side wall). Only the other cases (an end face or rim nearest)
    need GJK on the curved cylinder, which converges slowly."""
    r = par[0]
    h = par[1]
    d_seg = shape_triangle_distance(1, R, t, par_core, tri, pa, pb, upper + r, ws)
    lb = d_seg - r
    if lb >= upper:
        return lb
    s = (pa[0] - t[0]) * R[0, 2] + (pa[1] - t[1]) * R[1, 2] + (pa[2] - t[2]) * R[2, 2]
    if d_seg > r and abs(s) < h * (1.0 - 1e-9):
        for k in range(3):
            pa[k] += r * (pb[k] - pa[k]) / d_seg
        return lb
    return shape_triangle_distance(2, R, t, par, tri, pa, pb, upper, ws)


@numba.njit(cache=True)
def _query_shape(kind, R, t, par, vertices, faces, lo, hi, starts, counts, branching, leaf_size, best_in, pa_out, pb_out):
    """Best-first (depth-first by lower bound) minimum distance below ``best_in``; returns
    (distance, tree position of the triangle or -1, triangles tested)."""
    slo = np.empty(3)
    shi = np.empty(3)
    sc = np.empty(3)
    shape_bounds(kind, R, t, par, slo, shi, sc)
    sph = np.empty((MAX_SPHERES, 4))
    n_sph = shape_spheres(kind, R, t, par, sph)
    depth = counts.shape[0]
    cap = depth * branching + 2
    st_level = np.empty(cap, np.int64)
    st_idx = np.empty(cap, np.int64)
    st_lb = np.empty(cap)
    child_lb = np.empty(branching)
    child_ix = np.empty(branching, np.int64)
    tri = np.empty((3, 3))
    pa = np.empty(3)
    pb = np.empty(3)
    ws = make_workspace()
    par_core = par.copy()
    par_core[0] = 0.0  # a cylinder's axis segment, as a capsule of radius 0
    best = best_in
    best_pos = -1
    tested = 0
    sp = 0
    st_level[0] = 0
    st_idx[0] = 0
    st_lb[0] = _node_bound(slo, shi, sph, n_sph, lo, hi, 0)
    sp = 1
    n_tri = faces.shape[0]
    while sp > 0:
        sp -= 1
        # prune by the bound; once in contact (best <= 0) everything goes: the search stops at
        # the first contact, as seed 004's check does
        if st_lb[sp] >= best:
            continue
        level = st_level[sp]
        idx = st_idx[sp]
        if level == depth - 1:
            for f in range(idx * leaf_size, min(n_tri, (idx + 1) * leaf_size)):
                tlo0 = tlo1 = tlo2 = 1e300
                thi0 = thi1 = thi2 = -1e300
                for c in range(3):
                    v = faces[f, c]
                    tri[c, 0] = vertices[v, 0]
                    tri[c, 1] = vertices[v, 1]
                    tri[c, 2] = vertices[v, 2]
                    tlo0 = min(tlo0, tri[c, 0])
                    tlo1 = min(tlo1, tri[c, 1])
                    tlo2 = min(tlo2, tri[c, 2])
                    thi0 = max(thi0, tri[c, 0])
                    thi1 = max(thi1, tri[c, 1])
                    thi2 = max(thi2, tri[c, 2])
                if _bound(slo, shi, sph, n_sph, tlo0, tlo1, tlo2, thi0, thi1, thi2) >= best:
                    continue
                tested += 1
                if kind == 2:
                    d = _cylinder_triangle(R, t, par, par_core, tri, pa, pb, best, ws)
                else:
                    d = shape_triangle_distance(kind, R, t, par, tri, pa, pb, best, ws)
                if d < best:
                    best = d
                    best_pos = f
                    for k in range(3):
                        pa_out[k] = pa[k]
                        pb_out[k] = pb[k]
            continue
        c0 = idx * branching
        c1 = min(counts[level + 1], c0 + branching)
        m = 0
        base = starts[level + 1]
        for c in range(c0, c1):
            lb = _node_bound(slo, shi, sph, n_sph, lo, hi, base + c)
            if lb < best:
                # insertion sort, descending, so the nearest child is pushed last
                j = m
                while j > 0 and child_lb[j - 1] < lb:
                    child_lb[j] = child_lb[j - 1]
                    child_ix[j] = child_ix[j - 1]
                    j -= 1
                child_lb[j] = lb
                child_ix[j] = c
                m += 1
        for j in range(m):
            st_level[sp] = level + 1
            st_idx[sp] = child_ix[j]
            st_lb[sp] = child_lb[j]
            sp += 1
    return best, best_pos, tested


@numba.njit(cache=True)
def query_shapes(kinds, Rs, ts, pars, groups, n_groups, vertices, faces, lo, hi, starts, counts, branching, leaf_size,
                 cap, out_d, out_pa, out_pb, out_pos, out_shape):
    """Minimum distance per group of shapes (shapes of one group share the bound, so a far shape
    costs almost nothing once a near one is known); ``cap`` is the largest distance of interest.
    A group in contact gets distance 0 (its first contact ends its search; witness points are
    then a point of that contact). Returns the triangles tested."""
    pa = np.empty(3)
    pb = np.empty(3)
    for g in range(n_groups):
        out_d[g] = cap
        out_pos[g] = -1
        out_shape[g] = -1
    tested = 0
    # lowest shapes first: on a terrain (z up) they are usually the nearest, and their distance
    # bounds the search for the others of their group
    n_shapes = kinds.shape[0]
    low = np.empty(n_shapes)
    slo = np.empty(3)
    shi = np.empty(3)
    sc = np.empty(3)
    for s in range(n_shapes):
        shape_bounds(kinds[s], Rs[s], ts[s], pars[s], slo, shi, sc)
        low[s] = slo[2]
    for s in np.argsort(low):
        g = groups[s]
        if g < 0:
            continue
        d, pos, n = _query_shape(kinds[s], Rs[s], ts[s], pars[s], vertices, faces, lo, hi, starts, counts, branching,
                                 leaf_size, out_d[g], pa, pb)
        tested += n
        if pos >= 0 and d < out_d[g]:
            out_d[g] = d
            out_pos[g] = pos
            out_shape[g] = s
            for k in range(3):
                out_pa[g, k] = pa[k]
                out_pb[g, k] = pb[k]
    for g in range(n_groups):
        if out_d[g] < 0.0:
            out_d[g] = 0.0
    return tested


@numba.njit(cache=True)
def _ray_box(o, inv, lo, hi, row, tmax):
    t0 = 0.0
    t1 = tmax
    for k in range(3):
        a = (lo[row, k] - o[k]) * inv[k]
        b = (hi[row, k] - o[k]) * inv[k]
        if a > b:
            a, b = b, a
        if a > t0:
            t0 = a
        if b < t1:
            t1 = b
        if t0 > t1:
            return -1.0
    return t0


@numba.njit(cache=True)
def _ray_triangle(o, d, vertices, faces, f):
    """Möller-Trumbore, both sides; the ray parameter or -1."""
    a = faces[f, 0]
    b = faces[f, 1]
    c = faces[f, 2]
    e10 = vertices[b, 0] - vertices[a, 0]
    e11 = vertices[b, 1] - vertices[a, 1]
    e12 = vertices[b, 2] - vertices[a, 2]
    e20 = vertices[c, 0] - vertices[a, 0]
    e21 = vertices[c, 1] - vertices[a, 1]
    e22 = vertices[c, 2] - vertices[a, 2]
    p0 = d[1] * e22 - d[2] * e21
    p1 = d[2] * e20 - d[0] * e22
    p2 = d[0] * e21 - d[1] * e20
    det = e10 * p0 + e11 * p1 + e12 * p2
    if abs(det) < 1e-18:
        return -1.0
    inv = 1.0 / det
    s0 = o[0] - vertices[a, 0]
    s1 = o[1] - vertices[a, 1]
    s2 = o[2] - vertices[a, 2]
    u = (s0 * p0 + s1 * p1 + s2 * p2) * inv
    if u < 0.0 or u > 1.0:
        return -1.0
    q0 = s1 * e12 - s2 * e11
    q1 = s2 * e10 - s0 * e12
    q2 = s0 * e11 - s1 * e10
    v = (d[0] * q0 + d[1] * q1 + d[2] * q2) * inv
    if v < 0.0 or u + v > 1.0:
        return -1.0
    return (e20 * q0 + e21 * q1 + e22 * q2) * inv


@numba.njit(cache=True)
def ray_hits(origins, dirs, tmax, vertices, faces, lo, hi, starts, counts, branching, leaf_size, out_t, out_pos):
    """Nearest hit of each ray (unit ``dirs``) within ``tmax``: out_t (inf if none), out_pos."""
    depth = counts.shape[0]
    cap = depth * branching + 2
    st_level = np.empty(cap, np.int64)
    st_idx = np.empty(cap, np.int64)
    st_t = np.empty(cap)
    child_t = np.empty(branching)
    child_ix = np.empty(branching, np.int64)
    inv = np.empty(3)
    n_tri = faces.shape[0]
    for r in range(origins.shape[0]):
        o = origins[r]
        d = dirs[r]
        for k in range(3):
            inv[k] = 1.0 / d[k] if d[k] != 0.0 else 1e300
        best = tmax
        best_pos = -1
        t_root = _ray_box(o, inv, lo, hi, 0, best)
        sp = 0
        if t_root >= 0.0:
            st_level[0] = 0
            st_idx[0] = 0
            st_t[0] = t_root
            sp = 1
        while sp > 0:
            sp -= 1
            if st_t[sp] > best:
                continue
            level = st_level[sp]
            idx = st_idx[sp]
            if level == depth - 1:
                for f in range(idx * leaf_size, min(n_tri, (idx + 1) * leaf_size)):
                    th = _ray_triangle(o, d, vertices, faces, f)
                    if th >= 0.0 and th < best:
                        best = th
                        best_pos = f
                continue
            c0 = idx * branching
            c1 = min(counts[level + 1], c0 + branching)
            base = starts[level + 1]
            m = 0
            for c in range(c0, c1):
                tb = _ray_box(o, inv, lo, hi, base + c, best)
                if tb >= 0.0:
                    j = m
                    while j > 0 and child_t[j - 1] < tb:
                        child_t[j] = child_t[j - 1]
                        child_ix[j] = child_ix[j - 1]
                        j -= 1
                    child_t[j] = tb
                    child_ix[j] = c
                    m += 1
            for j in range(m):
                st_level[sp] = level + 1
                st_idx[sp] = child_ix[j]
                st_t[sp] = child_t[j]
                sp += 1
        out_t[r] = best if best_pos >= 0 else np.inf
        out_pos[r] = best_pos


@numba.njit(cache=True)
def shape_triangles_within(kind, R, t, par, eps, vertices, faces, lo, hi, starts, counts, branching, leaf_size, out_pos):
    """Tree positions of all triangles within ``eps`` of the shape (at most len(out_pos));
    returns how many were found (may exceed len(out_pos))."""
    slo = np.empty(3)
    shi = np.empty(3)
    sc = np.empty(3)
    shape_bounds(kind, R, t, par, slo, shi, sc)
    sph = np.empty((MAX_SPHERES, 4))
    n_sph = shape_spheres(kind, R, t, par, sph)
    depth = counts.shape[0]
    cap = depth * branching + 2
    st_level = np.empty(cap, np.int64)
    st_idx = np.empty(cap, np.int64)
    tri = np.empty((3, 3))
    pa = np.empty(3)
    pb = np.empty(3)
    ws = make_workspace()
    par_core = par.copy()
    par_core[0] = 0.0
    found = 0
    n_tri = faces.shape[0]
    st_level[0] = 0
    st_idx[0] = 0
    sp = 1
    while sp > 0:
        sp -= 1
        level = st_level[sp]
        idx = st_idx[sp]
        row = starts[level] + idx
        if _node_bound(slo, shi, sph, n_sph, lo, hi, row) > eps:
            continue
        if level == depth - 1:
            for f in range(idx * leaf_size, min(n_tri, (idx + 1) * leaf_size)):
                for c in range(3):
                    for k in range(3):
                        tri[c, k] = vertices[faces[f, c], k]
                if kind == 2:
                    d = _cylinder_triangle(R, t, par, par_core, tri, pa, pb, eps + 1e-12, ws)
                else:
                    d = shape_triangle_distance(kind, R, t, par, tri, pa, pb, eps + 1e-12, ws)
                if d <= eps:
                    if found < out_pos.shape[0]:
                        out_pos[found] = f
                    found += 1
            continue
        c0 = idx * branching
        c1 = min(counts[level + 1], c0 + branching)
        for c in range(c0, c1):
            st_level[sp] = level + 1
            st_idx[sp] = c
            sp += 1
    return found
