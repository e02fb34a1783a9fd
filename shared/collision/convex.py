"""Convex pieces of a body: where a body's triangles are the surfaces of closed convex solids.

Most bodies in a cell are unions of primitive shapes (boxes, cylinders, capsules, spheres), each
tessellated into a closed convex polyhedron. For those the distance between two bodies needs no
descent through triangle trees:

* the triangle-mesh distance of two bodies is the least distance over their pieces' pairs (a
  body's mesh is the union of its pieces' surfaces);
* for two closed convex surfaces whose solids are apart, the closest points of the solids lie on
  the surfaces, so the surface distance *is* the distance between the two convex hulls, which
  GJK finds exactly on the pieces' vertices (``gjk``) in a handful of support queries.

Only where two solids overlap (one piece inside the other without touching it) do the surfaces
and the hulls disagree; the scene then falls back to the exact triangle descent for that pair.

A piece is certified here only when it is provably its own convex hull's surface: a closed
2-manifold (every edge in exactly two faces, each directed edge once, so consistently wound)
whose every vertex lies behind every face's plane (within ``CONVEX_TOL`` of the piece's size).
A closed manifold inside the boundary of its hull is that whole boundary, so the surface and the
hull's boundary coincide. A body is convex-pieced only when every one of its shapes is
certified; any other body (a concave mesh file, a terrain) keeps the triangle descent alone.

Arrays (body frame): ``vertices`` (V, 3) holds each piece's hull vertices in turn (piece ``k``:
``start[k] .. start[k] + count[k]``); ``adj_start`` (V + 1,) and ``adj`` are the hull's edge
graph in CSR form with global vertex indices, for hill-climbing support queries; ``center``
(P, 3) and ``radius`` (P,) a bounding sphere per piece.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from shared.collision import model_cache

#: a vertex may lie this far (relative to the piece's extent) outside a face plane and the piece
#: still count as convex: far below the tessellation's rounding effects on distances (1e-13 m
#: on a 0.1 m shape)
CONVEX_TOL = 1e-12


@dataclass(frozen=True)
class ConvexPieces:
    vertices: np.ndarray
    start: np.ndarray
    count: np.ndarray
    adj_start: np.ndarray
    adj: np.ndarray
    center: np.ndarray
    radius: np.ndarray

    @property
    def n_pieces(self) -> int:
        return len(self.start)


def _closed_and_oriented(faces: np.ndarray) -> bool:
    """Every directed edge appears exactly once and its reverse exactly once."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    if np.any(directed[:, 0] == directed[:, 1]):
        return False
    n = int(faces.max()) + 1
    key = directed[:, 0] * n + directed[:, 1]
    rev = directed[:, 1] * n + directed[:, 0]
    key_sorted = np.sort(key)
    if np.any(key_sorted[1:] == key_sorted[:-1]):
        return False  # a directed edge twice: inconsistent winding or more than two faces
    found = np.searchsorted(key_sorted, rev)
    found = np.minimum(found, len(key_sorted) - 1)
    return bool(np.all(key_sorted[found] == rev))


def _behind_every_face(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """All vertices on the inner side of every face plane (either winding), within tolerance."""
    tris = vertices[faces]
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    keep = lengths > 0.0
    if not keep.any():
        return False
    normals = normals[keep] / lengths[keep, None]
    offsets = np.einsum("ij,ij->i", normals, tris[keep, 0])
    extent = float(np.ptp(vertices, axis=0).max())
    tol = CONVEX_TOL * max(extent, 1e-300)
    side = vertices @ normals.T - offsets  # (V, F): > 0 in front of the face
    return bool(side.max() <= tol or side.min() >= -tol)


def convex_piece(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]] | None:
    """The hull vertices and hull edges (local indices) of one piece given as a triangle soup,
    or ``None`` when the piece is not certified as a closed convex surface."""
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) < 4:
        return None
    used, local = np.unique(faces, return_inverse=True)
    local = local.reshape(faces.shape)
    pts = np.asarray(vertices, dtype=float)[used]
    if not _closed_and_oriented(local) or not _behind_every_face(pts, local):
        return None
    try:
        from scipy.spatial import ConvexHull, QhullError

        hull = ConvexHull(pts)
    except (QhullError, ValueError):  # flat or degenerate: no solid
        return None
    keep = hull.vertices
    renum = -np.ones(len(pts), dtype=np.int64)
    renum[keep] = np.arange(len(keep))
    edges: set[tuple[int, int]] = set()
    for tri in hull.simplices:
        a, b, c = (int(renum[v]) for v in tri)
        for u, v in ((a, b), (b, c), (c, a)):
            edges.add((min(u, v), max(u, v)))
    return np.ascontiguousarray(pts[keep]), sorted(edges)


def convex_pieces(vertices: np.ndarray, faces: np.ndarray, piece_faces: Sequence[tuple[int, int]]) -> ConvexPieces | None:
    """Certify each piece (a range of ``faces``) of one body; ``None`` unless all of them are."""
    if not piece_faces:
        return None
    all_vertices: list[np.ndarray] = []
    starts: list[int] = []
    counts: list[int] = []
    neighbours: list[list[int]] = []
    centers: list[np.ndarray] = []
    radii: list[float] = []
    offset = 0
    for lo, hi in piece_faces:
        piece = convex_piece(vertices, faces[lo:hi])
        if piece is None:
            return None
        pts, edges = piece
        lists: list[list[int]] = [[] for _ in range(len(pts))]
        for u, v in edges:
            lists[u].append(offset + v)
            lists[v].append(offset + u)
        neighbours.extend(lists)
        all_vertices.append(pts)
        starts.append(offset)
        counts.append(len(pts))
        c = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
        centers.append(c)
        radii.append(float(np.linalg.norm(pts - c, axis=1).max()) * (1.0 + 1e-12) + 1e-12)
        offset += len(pts)
    adj_start = np.zeros(offset + 1, dtype=np.int64)
    adj_start[1:] = np.cumsum([len(n) for n in neighbours])
    adj = np.array([u for n in neighbours for u in n], dtype=np.int64)
    return ConvexPieces(
        vertices=np.ascontiguousarray(np.concatenate(all_vertices)),
        start=np.array(starts, dtype=np.int64),
        count=np.array(counts, dtype=np.int64),
        adj_start=adj_start,
        adj=adj,
        center=np.array(centers),
        radius=np.array(radii),
    )


_FIELDS = ("vertices", "start", "count", "adj_start", "adj", "center", "radius")


def cached_convex_pieces(
    vertices: np.ndarray, faces: np.ndarray, piece_faces: Sequence[tuple[int, int]]
) -> ConvexPieces | None:
    """``convex_pieces``, read from the collision-model cache when one is configured (the hulls
    cost tens of milliseconds a tessellated capsule at every process start)."""
    if model_cache.folder() is None:
        return convex_pieces(vertices, faces, piece_faces)
    ranges = np.array(piece_faces, dtype=np.int64).reshape(-1, 2)

    def build() -> dict[str, np.ndarray]:
        pieces = convex_pieces(vertices, faces, piece_faces)
        if pieces is None:
            return {"certified": np.array(False), **{name: np.zeros(0) for name in _FIELDS}}
        return {"certified": np.array(True), **{name: getattr(pieces, name) for name in _FIELDS}}

    arrays = model_cache.cached_arrays(
        "convex", (np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64), ranges, CONVEX_TOL),
        ("certified", *_FIELDS), build,
    )
    if not bool(arrays["certified"]):
        return None
    return ConvexPieces(**{name: np.ascontiguousarray(arrays[name]) for name in _FIELDS})
