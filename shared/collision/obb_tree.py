"""The hybrid bounding-volume hierarchy of seed 002 for one body, built once (immutable).

Per body: a bounding sphere (centre of the body's AABB, radius to the farthest vertex), the
vertices of its convex hull (to rebuild the world AABB exactly at any pose, as the paper
rebuilds the AABB after a rotation), and an OBB tree built top down:

* a node's box axes are the eigenvectors of the area-weighted covariance of its triangles
  (Gottschalk: ``C_ij = 1/a_H sum_k a_k/12 (9 m_ki m_kj + p_ki p_kj + q_ki q_kj + r_ki r_kj)
  - m_Hi m_Hj``); when eigenvalues repeat (a cube, a square peg) the eigenvectors are arbitrary
  in the repeated plane, so more candidate bases are tried (the body axes and the frames of
  the node's largest triangle, x along each edge) and the smallest box is kept;
* extents come from projecting the node's vertices on the axes;
* a node splits by the plane through the mean of its vertices perpendicular to its longest axis,
  each triangle going to the side of its centroid; if one side would be empty the other axes are
  tried by decreasing length; if all fail (or ``leaf_size`` is reached) the node is a leaf.

Arrays are flat (preorder): node ``i`` has ``center[i]`` (3,), ``axes[i]`` (3, 3) with the box
axes as columns, ``half[i]`` (3,), ``radius[i]`` (bounding-sphere radius about ``center[i]``),
``left[i]``/``right[i]`` (-1 for a leaf), ``tri_start[i]``/``tri_count[i]`` (its triangles in
``tris``). ``tris`` (T, 3, 3) holds triangle vertices in tree order, ``tri_ids`` their ids in the
body mesh.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from shared.collision import model_cache

#: absolute padding (m) added to every box and sphere so rounding never shaves off a vertex
PAD = 1e-12


@dataclass(frozen=True)
class OBBTree:
    center: np.ndarray
    axes: np.ndarray
    half: np.ndarray
    radius: np.ndarray
    left: np.ndarray
    right: np.ndarray
    tri_start: np.ndarray
    tri_count: np.ndarray
    tris: np.ndarray
    tri_ids: np.ndarray
    sphere_center: np.ndarray
    sphere_radius: float
    hull_vertices: np.ndarray

    @property
    def n_nodes(self) -> int:
        return len(self.center)

    @property
    def depth(self) -> int:
        depth = np.zeros(self.n_nodes, dtype=int)
        for i in range(self.n_nodes):
            for c in (self.left[i], self.right[i]):
                if c >= 0:
                    depth[c] = depth[i] + 1
        return int(depth.max()) + 1


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` for (..., 3) arrays without its axis bookkeeping (it dominated tree builds)."""
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def triangle_areas(tris: np.ndarray) -> np.ndarray:
    """Area of each triangle of ``tris`` (k, 3, 3)."""
    return 0.5 * np.sqrt((_cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]) ** 2).sum(axis=-1))


def covariance_axes(tris: np.ndarray, area: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Gottschalk's area-weighted triangle covariance of ``tris`` (k, 3, 3): (eigenvalues
    ascending, eigenvectors as columns, right-handed). ``area``: the triangles' areas if known."""
    p, q, r = tris[:, 0], tris[:, 1], tris[:, 2]
    if area is None:
        area = triangle_areas(tris)
    total = area.sum()
    if total <= 0.0:  # all slivers: plain vertex covariance
        pts = tris.reshape(-1, 3)
        cov = np.cov(pts.T, bias=True) if len(pts) > 1 else np.zeros((3, 3))
    else:
        m = (p + q + r) / 3.0
        m_h = (area[:, None] * m).sum(axis=0) / total
        s = 9.0 * np.einsum("k,ki,kj->ij", area, m, m)
        for v in (p, q, r):
            s += np.einsum("k,ki,kj->ij", area, v, v)
        cov = s / (12.0 * total) - np.outer(m_h, m_h)
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    if np.linalg.det(v) < 0:
        v[:, 2] = -v[:, 2]
    return w, v


def _box_in_basis(pts: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    proj = pts @ basis
    lo, hi = proj.min(axis=0), proj.max(axis=0)
    return basis @ ((lo + hi) / 2.0), (hi - lo) / 2.0


def _cross3(a, b) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _triangle_frames(tri: np.ndarray) -> list[np.ndarray]:
    """Right-handed frames with z along the triangle's normal and x along each of its edges
    (plain float arithmetic: called once per node, numpy's per-call cost dominated)."""
    p0, p1, p2 = (tuple(map(float, v)) for v in tri)
    e0 = (p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2])
    e1 = (p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2])
    e2 = (p0[0] - p2[0], p0[1] - p2[1], p0[2] - p2[2])
    n = _cross3(e0, (p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]))
    ln = math.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)
    if ln <= 0.0:
        return []
    z = (n[0] / ln, n[1] / ln, n[2] / ln)
    frames = []
    for e in (e0, e1, e2):
        le = math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2)
        if le > 0.0:
            x = (e[0] / le, e[1] / le, e[2] / le)
            frames.append(np.array([x, _cross3(z, x), z]).T)
    return frames


def fit_obb(tris: np.ndarray, areas: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """OBB of triangles ``(k, 3, 3)``: (center (3,), axes (3, 3) as columns, half extents (3,))."""
    pts = tris.reshape(-1, 3)
    if areas is None:
        areas = triangle_areas(tris)
    _, cov_basis = covariance_axes(tris, areas)
    candidates = [cov_basis, np.eye(3)]
    candidates += _triangle_frames(tris[int(np.argmax(areas))])
    best = None
    for basis in candidates:
        center, half = _box_in_basis(pts, basis)
        eps = 1e-6 * max(float(half.max()), 1e-12)
        score = float(np.prod(half + eps))
        if best is None or score < best[0] * (1.0 - 1e-9):
            best = (score, center, basis, half)
    _, center, basis, half = best
    return center, basis, half + PAD


def _split(tris: np.ndarray, idx: np.ndarray, axes: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    sub = tris[idx]
    mean = sub.reshape(-1, 3).mean(axis=0)
    centroids = sub.mean(axis=1)
    for a in np.argsort(-half, kind="stable"):
        side = (centroids - mean) @ axes[:, a] < 0.0
        n_left = int(side.sum())
        if 0 < n_left < len(idx):
            return idx[side], idx[~side]
    return None


def _hull_vertices(vertices: np.ndarray) -> np.ndarray:
    try:
        from scipy.spatial import ConvexHull

        return np.ascontiguousarray(vertices[ConvexHull(vertices).vertices])
    except Exception:  # flat or tiny point sets: every vertex (still exact for the AABB)
        return np.ascontiguousarray(np.unique(vertices, axis=0))


def build_obb_tree(
    vertices: np.ndarray, faces: np.ndarray, leaf_size: int = 1, compiled: bool = True, cache: bool = True
) -> OBBTree:
    """Build the hierarchy of one body (vertices (V, 3) and faces (F, 3) in the body frame).
    ``compiled``: the numba build (``obb_build``); False runs this module's Python reference of
    the same algorithm (kept to check the compiled one against). The compiled build is read from
    ``model_cache`` when a caller configured one and ``cache`` (identical arrays)."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    if cache and compiled and len(faces) and model_cache.folder() is not None:
        # the same build, read from the on-disk cache when these triangles were built before
        arrays = model_cache.cached_arrays(
            "obb", (vertices, faces, int(leaf_size), PAD), _TREE_FIELDS,
            lambda: _tree_arrays(build_obb_tree(vertices, faces, leaf_size, compiled, cache=False)),
        )
        return _tree_from_arrays(arrays)
    tris_all = np.ascontiguousarray(vertices[faces])
    areas_all = triangle_areas(tris_all)
    if compiled and len(faces):
        from shared.collision.obb_build import build_nodes

        center, axes, half, radius, left, right, starts, counts, tri_ids = build_nodes(
            tris_all, areas_all, int(leaf_size), PAD)
        return _tree(vertices, tris_all, center, axes, half, radius, left, right, starts, counts, tri_ids)
    centers, axes_l, halves, radii, lefts, rights, starts, counts = [], [], [], [], [], [], [], []
    order: list[np.ndarray] = []
    n_tris_placed = 0
    # explicit stack of (triangle ids, parent node, is_left)
    stack: list[tuple[np.ndarray, int, bool]] = [(np.arange(len(faces)), -1, False)]
    while stack:
        idx, parent, is_left = stack.pop()
        node = len(centers)
        if parent >= 0:
            (lefts if is_left else rights)[parent] = node
        sub = tris_all[idx]
        c, ax, h = fit_obb(sub, areas_all[idx])
        centers.append(c)
        axes_l.append(ax)
        halves.append(h)
        radii.append(float(np.linalg.norm(sub.reshape(-1, 3) - c, axis=1).max()) + PAD)
        lefts.append(-1)
        rights.append(-1)
        parts = _split(tris_all, idx, ax, h) if len(idx) > leaf_size else None
        if parts is None:
            starts.append(n_tris_placed)
            counts.append(len(idx))
            order.append(idx)
            n_tris_placed += len(idx)
        else:
            starts.append(-1)
            counts.append(0)
            # pushed right first so the left child is numbered next (preorder)
            stack.append((parts[1], node, False))
            stack.append((parts[0], node, True))
    return _tree(vertices, tris_all, np.array(centers), np.array(axes_l), np.array(halves), np.array(radii),
                 np.array(lefts, dtype=np.int64), np.array(rights, dtype=np.int64), np.array(starts, dtype=np.int64),
                 np.array(counts, dtype=np.int64), np.concatenate(order))


_TREE_FIELDS = tuple(f for f in OBBTree.__dataclass_fields__)


def _tree_arrays(tree: OBBTree) -> dict[str, np.ndarray]:
    return {name: np.asarray(getattr(tree, name)) for name in _TREE_FIELDS}


def _tree_from_arrays(arrays: dict[str, np.ndarray]) -> OBBTree:
    fields = {name: np.ascontiguousarray(arrays[name]) for name in _TREE_FIELDS}
    fields["sphere_radius"] = float(arrays["sphere_radius"])
    return OBBTree(**fields)


def _tree(vertices, tris_all, center, axes, half, radius, left, right, starts, counts, tri_ids) -> OBBTree:
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    sphere_center = (lo + hi) / 2.0
    sphere_radius = float(np.linalg.norm(vertices - sphere_center, axis=1).max()) + PAD
    return OBBTree(
        center=center,
        axes=axes,
        half=half,
        radius=radius,
        left=left,
        right=right,
        tri_start=starts,
        tri_count=counts,
        tris=np.ascontiguousarray(tris_all[tri_ids]),
        tri_ids=tri_ids.astype(np.int64),
        sphere_center=sphere_center,
        sphere_radius=sphere_radius,
        hull_vertices=_hull_vertices(vertices),
    )


def swept_rectangles(axes: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Each box as a swept-sphere rectangle (RSS) that contains it, for distance bounds.

    The rectangle spans the box's two longest axes (same centre, half extents ``a >= b``) and
    the sweeping radius is the smallest half extent ``r``: a box point ``(x, y, z)`` lies within
    ``|z| <= r`` of the rectangle point ``(x, y, 0)``. For the flat nodes of a tessellated
    surface (a leaf triangle has ``r`` = the padding) the distance between two rectangles, less
    both radii, is far tighter than the boxes' separating-axis gap. Rows (``(N, 12)``): ``u``
    (3), ``v`` (3), the rectangle's normal ``w`` (3), ``a``, ``b``, ``r``.
    """
    order = np.argsort(-half, axis=1, kind="stable")
    n = len(half)
    rows = np.arange(n)
    out = np.empty((n, 12))
    for k in range(3):
        out[:, 3 * k:3 * k + 3] = axes[rows, :, order[:, k]]
    out[:, 9] = half[rows, order[:, 0]]
    out[:, 10] = half[rows, order[:, 1]]
    out[:, 11] = half[rows, order[:, 2]]
    return out
