"""coal on the very same triangles, pair by pair: the reference the collision core is checked
and timed against (BVHModelOBBRSS per body, gjk_tolerance 1e-9, triangle ids via
num_max_contacts > 1)."""

from __future__ import annotations

import coal
import numpy as np

from shared.collision.scene import SceneModel


class CoalScene:
    def __init__(self, model: SceneModel, max_contacts: int = 100000) -> None:
        self.model = model
        self.geoms = []
        for body in model.bodies:
            bvh = coal.BVHModelOBBRSS()
            bvh.beginModel(len(body.mesh.faces), len(body.mesh.vertices))
            bvh.addVertices(np.asarray(body.mesh.vertices, dtype=float))
            bvh.addTriangles(np.asarray(body.mesh.faces, dtype=np.int64))
            bvh.endModel()
            self.geoms.append(bvh)
        self.objects = [coal.CollisionObject(g, coal.Transform3s()) for g in self.geoms]
        self.creq = coal.CollisionRequest()
        self.creq.num_max_contacts = max_contacts
        self.creq.enable_contact = False
        self.creq.gjk_tolerance = 1e-9
        self.creq_first = coal.CollisionRequest()
        self.creq_first.num_max_contacts = 1
        self.creq_first.gjk_tolerance = 1e-9
        self.dreq = coal.DistanceRequest()
        self.dreq.gjk_tolerance = 1e-9
        self.pairs = [tuple(map(int, p)) for p in model.pairs]

    def set_poses(self, world: np.ndarray) -> None:
        for obj, T in zip(self.objects, world):
            obj.setTransform(coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3])))

    def collide(self, mode: np.ndarray, all_contacts: bool = True):
        """Per pair: (hit, set of (tri_a, tri_b)) for pairs with mode > 0."""
        out = {}
        req = self.creq if all_contacts else self.creq_first
        for p, (a, b) in enumerate(self.pairs):
            if mode[p] == 0:
                continue
            res = coal.CollisionResult()
            coal.collide(self.objects[a], self.objects[b], req, res)
            tris = {(c.b1, c.b2) for c in res.getContacts()} if all_contacts else set()
            out[p] = (res.isCollision(), tris)
        return out

    def collide_pair(self, a: int, b: int, all_contacts: bool = True) -> tuple[bool, set[tuple[int, int]]]:
        """Bodies ``a`` and ``b`` (indices in ``model.bodies``): (hit, set of (tri_a, tri_b))."""
        res = coal.CollisionResult()
        coal.collide(self.objects[a], self.objects[b], self.creq if all_contacts else self.creq_first, res)
        return res.isCollision(), ({(c.b1, c.b2) for c in res.getContacts()} if all_contacts else set())

    def distance_pair(self, a: int, b: int) -> float:
        res = coal.DistanceResult()
        coal.distance(self.objects[a], self.objects[b], self.dreq, res)
        return res.min_distance

    def distances(self, mode: np.ndarray):
        """Per pair with mode 2: (distance, point on a, point on b) in the world frame."""
        out = {}
        for p, (a, b) in enumerate(self.pairs):
            if mode[p] != 2:
                continue
            res = coal.DistanceResult()
            coal.distance(self.objects[a], self.objects[b], self.dreq, res)
            out[p] = (res.min_distance, np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2()))
        return out


def dragging_path(robot, n: int, rng: np.random.Generator, step: float = 0.004) -> np.ndarray:
    """Joint vectors as when the operator drags: straight joint-space runs between random
    goals in steps of at most ``step`` rad, ``(n, dof)``."""
    lo, hi = robot.lower, robot.upper
    out = []
    q = rng.uniform(lo, hi)
    while len(out) < n:
        goal = rng.uniform(lo, hi)
        k = max(int(np.abs(goal - q).max() / step), 1)
        for s in np.linspace(0.0, 1.0, k + 1)[1:]:
            out.append(q + s * (goal - q))
        q = goal
    return np.array(out[:n])
