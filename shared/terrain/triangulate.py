"""2.5D Delaunay triangulation of a terrain cloud: Delaunay on the ground (XY) projection, each
vertex keeping its height. Shewchuk's Triangle (PyPI ``triangle``) by default, about 6x faster
than ``scipy.spatial.Delaunay`` (Qhull) on 400k points; Qhull stays as the reference.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from shared.errors import InputError

log = logging.getLogger(__name__)

METHODS = ("triangle", "scipy")


@dataclass(frozen=True)
class TerrainMesh:
    """Triangles of a terrain: ``vertices`` (V, 3) float64 metres, ``faces`` (F, 3) int32, each
    counter-clockwise seen from above (normals point up)."""

    vertices: np.ndarray
    faces: np.ndarray

    @property
    def n_triangles(self) -> int:
        return int(self.faces.shape[0])

    def normals(self) -> np.ndarray:
        """Unit normals (F, 3) of the faces (pointing up for a height field)."""
        v = self.vertices[self.faces]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        return n / np.linalg.norm(n, axis=1, keepdims=True)


def triangulate_25d(points: np.ndarray, method: str = "triangle") -> TerrainMesh:
    """Delaunay triangulation of the XY projection of ``points`` (N, 3). Points should be
    filtered first (``shared.terrain.filter``): coincident ground positions are not allowed."""
    points = np.ascontiguousarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) < 3:
        raise InputError(f"triangulation needs (N >= 3, 3) points, got shape {points.shape}")
    if method == "triangle":
        import triangle

        # 'Q' quiet, no other switches: plain Delaunay of the vertices (no added points)
        out = triangle.triangulate({"vertices": points[:, :2]}, "Q")
        faces = np.asarray(out.get("triangles", np.zeros((0, 3))), dtype=np.int32)
        if len(out["vertices"]) != len(points):
            raise InputError("triangulation merged coincident ground points: filter the cloud first")
    elif method == "scipy":
        from scipy.spatial import Delaunay

        faces = Delaunay(points[:, :2]).simplices.astype(np.int32)
    else:
        raise InputError(f"unknown triangulation method {method!r}; valid: {', '.join(METHODS)}")
    if len(faces) == 0:
        raise InputError("triangulation produced no triangles: the points are collinear seen from above")
    # orient every face counter-clockwise in XY so normals point up
    a, b, c = (points[faces[:, i], :2] for i in range(3))
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    flip = cross < 0
    faces[flip] = faces[flip][:, [0, 2, 1]]
    keep = cross != 0
    if not keep.all():
        log.debug("dropping %d zero-area triangles", int((~keep).sum()))
        faces = faces[keep]
    return TerrainMesh(points, np.ascontiguousarray(faces))
