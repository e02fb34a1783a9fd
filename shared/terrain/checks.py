"""Both terrain checks for one arm configuration.

(a) ``sensor_check``: the paper's virtual-sensor scheme (seed 004 §3.1 step 3, §3.2). Each sensor
    segment AB is cast as a ray from A through B against the terrain tree; a hit at range d_R
    gives the collision segment from A to the hit. The sensor collides when d_R <= d_S (its own
    length); otherwise its clearance is d_RS = d_R - d_S, and the arm's sensor distance is the
    smallest d_RS. It measures along the link axis, not the shortest way, and only on the sensor
    lines: it over-states clearance (ground beside or between sensors, beyond a capsule's end)
    and can under-state it (sensors on a circle around a box stand outside the box).
(b) ``exact_check``: the true minimum Euclidean distance between the link shapes and the
    terrain triangles, with witness points, the shape and the triangle; on contact, the
    triangles touching the arm (the console's red triangles).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shared.terrain.arm import ArmModel
from shared.terrain.tree import TerrainTree, query_shapes, ray_hits, shape_triangles_within

#: default sensor range (m): farther ground is "no reading"
SENSOR_RANGE = 2.0
#: at most this many contact triangles are listed
MAX_CONTACT_TRIANGLES = 4096


@dataclass(frozen=True)
class ExactReport:
    """Minimum distance (m; <= 0 on contact) between the arm and the terrain."""

    distance: float
    in_collision: bool
    shape: str  # the arm shape holding the nearest point
    world_p_arm: np.ndarray  # witness on the arm (3,)
    world_p_terrain: np.ndarray  # witness on the terrain (3,)
    triangle: int  # face index in the terrain mesh, -1 if nothing within the cap
    contact_triangles: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    per_shape: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class SensorReport:
    """The virtual-sensor check: per sensor (M of them) its ends, part, ray range d_R (inf when
    nothing within range), length d_S, collision flag and clearance d_RS (inf when no reading)."""

    A: np.ndarray
    B: np.ndarray
    part: np.ndarray
    d_R: np.ndarray
    d_S: np.ndarray
    collides: np.ndarray
    d_RS: np.ndarray
    hit_triangle: np.ndarray

    @property
    def in_collision(self) -> bool:
        return bool(self.collides.any())

    @property
    def distance(self) -> float:
        """The paper's arm-to-ground distance: the smallest d_RS (0 on collision, inf if blind)."""
        if self.in_collision:
            return 0.0
        return float(self.d_RS.min()) if len(self.d_RS) else float("inf")

    def collision_segments(self) -> tuple[np.ndarray, np.ndarray]:
        """The paper's d_R segments: from each sensor's A to its hit point (rays that hit only)."""
        hit = np.isfinite(self.d_R)
        u = (self.B - self.A) / self.d_S[:, None]
        return self.A[hit], self.A[hit] + u[hit] * self.d_R[hit, None]


class TerrainChecker:
    """Checks of one arm over one terrain tree; ``world_T_base`` places the arm in the terrain."""

    def __init__(self, tree: TerrainTree, arm: ArmModel, world_T_base: np.ndarray) -> None:
        self.tree = tree
        self.arm = arm
        self.world_T_base = np.asarray(world_T_base, dtype=float)
        self._arrays = tree.arrays()

    # -- (b) exact -------------------------------------------------------------------------
    def group_distances(self, q: np.ndarray, groups: np.ndarray, n_groups: int, cap: float = np.inf):
        """Per group of shapes (``groups[s]`` = group of shape s, -1 to skip): distance, witness
        points, tree position of the triangle and shape index."""
        Rs, ts = self.arm.shape_poses(self.world_T_base, q)
        out_d = np.empty(n_groups)
        out_pa = np.zeros((n_groups, 3))
        out_pb = np.zeros((n_groups, 3))
        out_pos = np.empty(n_groups, np.int64)
        out_shape = np.empty(n_groups, np.int64)
        query_shapes(self.arm.kinds, Rs, ts, self.arm.pars, np.asarray(groups, np.int64), n_groups, *self._arrays,
                     float(cap), out_d, out_pa, out_pb, out_pos, out_shape)
        return out_d, out_pa, out_pb, out_pos, out_shape

    def min_distance(self, q: np.ndarray) -> float:
        """The arm's minimum distance alone (the fast path)."""
        d, *_ = self.group_distances(q, np.zeros(len(self.arm.shapes), np.int64), 1)
        return float(d[0])

    def exact_check(self, q: np.ndarray, per_shape: bool = False, cap: float = np.inf) -> ExactReport:
        """Minimum distance with witnesses; ``per_shape`` adds every shape's own distance."""
        n = len(self.arm.shapes)
        d, pa, pb, pos, shp = self.group_distances(q, np.zeros(n, np.int64), 1, cap)
        per: dict[str, float] = {}
        if per_shape:
            ds, *_ = self.group_distances(q, np.arange(n), n, cap)
            per = {s.name: float(v) for s, v in zip(self.arm.shapes, ds)}
        contacts = np.zeros(0, np.int64)
        if d[0] <= 0.0:
            contacts = self.contact_triangles(q)
        found = pos[0] >= 0
        return ExactReport(
            distance=float(d[0]), in_collision=bool(d[0] <= 0.0), shape=self.arm.shapes[shp[0]].name if found else "",
            world_p_arm=pa[0].copy(), world_p_terrain=pb[0].copy(),
            triangle=int(self.tree.face_ids[pos[0]]) if found else -1, contact_triangles=contacts, per_shape=per,
        )

    def triangles_near_shapes(self, Rs: np.ndarray, ts: np.ndarray, kinds: np.ndarray, pars: np.ndarray, eps: float) -> np.ndarray:
        """Mesh face indices within ``eps`` of any of the given posed shapes (sorted, unique)."""
        out = np.empty(MAX_CONTACT_TRIANGLES, np.int64)
        found = []
        for s in range(len(kinds)):
            k = shape_triangles_within(int(kinds[s]), Rs[s], ts[s], pars[s], float(eps), *self._arrays, out)
            found.append(out[: min(k, len(out))].copy())
        pos = np.unique(np.concatenate(found)) if found else np.zeros(0, np.int64)
        return np.sort(self.tree.face_ids[pos].astype(np.int64))

    def contact_triangles(self, q: np.ndarray, eps: float = 0.0) -> np.ndarray:
        """Mesh face indices of the triangles within ``eps`` of the arm (touching it for 0)."""
        Rs, ts = self.arm.shape_poses(self.world_T_base, q)
        return self.triangles_near_shapes(Rs, ts, self.arm.kinds, self.arm.pars, eps)

    # -- (a) virtual sensors ---------------------------------------------------------------
    def sensor_check(self, q: np.ndarray, parts: tuple[int, ...] | None = None, max_range: float = SENSOR_RANGE) -> SensorReport:
        """The paper's check with the sensors of ``parts`` (all parts by default)."""
        A, B, owner = self.arm.sensors(self.world_T_base, q, parts)
        seg = B - A
        d_S = np.linalg.norm(seg, axis=1)
        dirs = np.ascontiguousarray(seg / d_S[:, None])
        t = np.empty(len(A))
        pos = np.empty(len(A), np.int64)
        ray_hits(np.ascontiguousarray(A), dirs, float(max_range), *self._arrays, t, pos)
        collides = t <= d_S
        d_RS = np.where(collides, 0.0, t - d_S)
        tri = np.where(pos >= 0, self.tree.face_ids[np.maximum(pos, 0)], -1)
        return SensorReport(A, B, owner, t, d_S, collides, d_RS, tri)
