"""coal (FCL's successor) on the same geometry: the reference the exact check is compared to in
tests and in the benchmark. Not used on the fast path."""

from __future__ import annotations

import numpy as np

from shared.terrain.arm import ArmModel
from shared.terrain.gjk import BOX, CAPSULE, CYLINDER, SPHERE
from shared.terrain.triangulate import TerrainMesh


def coal_terrain(mesh: TerrainMesh):
    """The terrain as a coal BVH (OBBRSS) model."""
    import coal

    model = coal.BVHModelOBBRSS()
    model.beginModel(mesh.n_triangles, len(mesh.vertices))
    model.addVertices(np.ascontiguousarray(mesh.vertices, dtype=float))
    model.addTriangles(np.ascontiguousarray(mesh.faces, dtype=np.int64))
    model.endModel()
    return model


def coal_shapes(arm: ArmModel) -> list:
    """The arm's shapes as coal primitives (same parameters)."""
    import coal

    out = []
    for s in arm.shapes:
        r, h, hx, hy, hz = s.par
        if s.kind == SPHERE:
            out.append(coal.Sphere(r))
        elif s.kind == CAPSULE:
            out.append(coal.Capsule(r, 2 * h))
        elif s.kind == CYLINDER:
            out.append(coal.Cylinder(r, 2 * h))
        elif s.kind == BOX:
            out.append(coal.Box(2 * hx, 2 * hy, 2 * hz))
    return out


def coal_min_distance(terrain, shapes: list, Rs: np.ndarray, ts: np.ndarray, tol: float = 1e-9):
    """Minimum distance over the shapes and the witness points (arm, terrain) with coal."""
    import coal

    req = coal.DistanceRequest()
    req.gjk_tolerance = tol
    identity = coal.Transform3s()
    best = (np.inf, None, None)
    for shape, R, t in zip(shapes, Rs, ts):
        res = coal.DistanceResult()
        d = coal.distance(shape, coal.Transform3s(R, t), terrain, identity, req, res)
        if d < best[0]:
            best = (d, np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2()))
    return best
