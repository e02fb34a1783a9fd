"""Scene collision checks: the robot at q among the cell's objects (seed 002's hybrid hierarchy).

``SceneModel`` is built once per cell and never mutated; ``SceneData`` is one caller's working
state (pinocchio data, coherence caches, output buffers). Typical use::

    model = SceneModel.from_cell(cell)
    data = model.new_data()                 # one per user/thread (or let check() use a per-thread one)
    report = model.check(q, data=data)      # colliding?, which bodies, which triangles, distances
    report.colliding, report.pairs, report.min_distance, report.distance("link6", "peg")

Bodies are named ``link0`` .. ``link{dof}`` (link 0 is the base) and by the cell's object names.
Pairs checked: robot links that are not adjacent in the chain and not declared always in
contact, every link with every object, and object pairs where at least one object is movable.
Object pairs that already interfere in the cell as loaded (the peg resting on the floor of its
hole) are *resting contacts*: they are skipped unless ``object_poses`` moves one of them.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Literal, NamedTuple

import numpy as np

from shared.collision import kernels
from shared.collision.convex import ConvexPieces, cached_convex_pieces
from shared.collision.mesh_model import BodyMesh, body_mesh
from shared.collision.obb_tree import OBBTree, build_obb_tree, swept_rectangles
from shared.errors import InputError, UnknownNameError

DistanceSelection = Literal["all", "none"] | Iterable[str | tuple[str, str]] | None

_INITIAL_TRI_CAPACITY = 4096
_NO_Q = np.zeros(0)
_NOTHING_MOVED: frozenset[str] = frozenset()


class InterferingPair(NamedTuple):
    """Two bodies whose surfaces meet, with the ids of their interfering triangles (sorted,
    unique; ids index the body's mesh faces, see ``SceneModel.mesh``)."""

    a: str
    b: str
    tris_a: np.ndarray
    tris_b: np.ndarray


@dataclass(frozen=True)
class PairDistance:
    """Separation of two bodies: ``distance`` (m, 0 when they interfere) and the closest points
    in the world frame (``nan`` when they interfere: no unique witness pair)."""

    a: str
    b: str
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray

    @property
    def colliding(self) -> bool:
        return self.distance == 0.0


class CollisionReport:
    """The answer of one scene check.

    ``colliding``: any checked pair interferes. ``pairs``: the interfering body pairs with their
    triangle ids. ``triangle_pairs[(a, b)]``: the (k, 2) interfering triangle id pairs.
    ``min_distance`` / ``nearest``: over the pairs whose distance was asked (``None`` if none);
    ``distances[(a, b)]`` per pair (use ``distance(a, b)`` for an order-free lookup).

    Built by ``SceneModel`` from the kernel's arrays (which it owns); every field but
    ``colliding`` is worked out when first read, so a caller that only wants the yes/no answer
    pays for nothing else.
    """

    __slots__ = ("colliding", "_names", "_hit", "_res", "_mode", "_tris", "_pairs", "_tri_pairs",
                 "_distances", "_nearest")

    def __init__(self, names, hit, res, mode, tris) -> None:
        self.colliding = tris is not None  # every interfering pair reports a triangle pair
        self._names = names
        self._hit = hit
        self._res = res  # per pair: distance, point on a (3), point on b (3)
        self._mode = mode
        self._tris = tris  # (pair, tri a, tri b) rows, copied out of the caller's buffers
        self._pairs: tuple[InterferingPair, ...] | None = None
        self._tri_pairs: dict[tuple[str, str], np.ndarray] | None = None
        self._distances: dict[tuple[str, str], PairDistance] | None = None
        self._nearest: tuple[float | None, PairDistance | None] | None = None

    def __repr__(self) -> str:
        return f"CollisionReport(colliding={self.colliding}, pairs={[(p.a, p.b) for p in self.pairs]}, min_distance={self.min_distance})"

    def _interference(self) -> None:
        pairs: list[InterferingPair] = []
        tri_pairs: dict[tuple[str, str], np.ndarray] = {}
        if self._tris is not None:
            order, ta, tb = self._tris
            for p in np.flatnonzero(self._hit):
                sel = order == p
                tp = np.column_stack([ta[sel], tb[sel]])
                a, b = self._names[p]
                tri_pairs[(a, b)] = tp
                pairs.append(InterferingPair(a, b, np.unique(tp[:, 0]), np.unique(tp[:, 1])))
        self._pairs = tuple(pairs)
        self._tri_pairs = tri_pairs

    @property
    def pairs(self) -> tuple[InterferingPair, ...]:
        if self._pairs is None:
            self._interference()
        return self._pairs

    @property
    def triangle_pairs(self) -> dict[tuple[str, str], np.ndarray]:
        if self._tri_pairs is None:
            self._interference()
        return self._tri_pairs

    def _nearest_pair(self) -> tuple[float | None, PairDistance | None]:
        if self._nearest is None:
            asked = self._mode == 2
            if not asked.any():
                self._nearest = (None, None)
            else:
                masked = np.where(asked, self._res[:, 0], np.inf)
                p = int(np.argmin(masked))
                d = float(masked[p])
                a, b = self._names[p]
                self._nearest = (d, PairDistance(a, b, d, self._res[p, 1:4].copy(), self._res[p, 4:7].copy()))
        return self._nearest

    def nearest_among(self, keep: np.ndarray) -> PairDistance | None:
        """The nearest pair among those whose distance was asked and that ``keep`` (one bool per
        pair of the model's ``pair_names``) keeps; ``None`` when none is left."""
        masked = np.where((self._mode == 2) & keep, self._res[:, 0], np.inf)
        if not len(masked) or not np.isfinite(masked).any():
            return None
        return self._pair_distance(int(np.argmin(masked)))

    @property
    def min_distance(self) -> float | None:
        return self._nearest_pair()[0]

    @property
    def nearest(self) -> PairDistance | None:
        return self._nearest_pair()[1]

    @property
    def distances(self) -> dict[tuple[str, str], PairDistance]:
        if self._distances is None:
            self._distances = {self._names[p]: self._pair_distance(p) for p in np.flatnonzero(self._mode == 2)}
        return self._distances

    def _pair_distance(self, p: int) -> PairDistance:
        a, b = self._names[p]
        return PairDistance(a, b, float(self._res[p, 0]), self._res[p, 1:4].copy(), self._res[p, 4:7].copy())

    def distance(self, a: str, b: str) -> PairDistance:
        """Distance between bodies ``a`` and ``b`` (either order; swaps the points to match)."""
        d = self.distances
        if (a, b) in d:
            return d[(a, b)]
        if (b, a) in d:
            r = d[(b, a)]
            return PairDistance(a, b, r.distance, r.point_b, r.point_a)
        raise UnknownNameError("pair with a distance", f"{a}/{b}", [f"{x}/{y}" for x, y in d])

    def interfering_triangles(self, body: str) -> np.ndarray:
        """Sorted ids of ``body``'s triangles that interfere with anything (for red painting)."""
        ids = [p.tris_a for p in self.pairs if p.a == body] + [p.tris_b for p in self.pairs if p.b == body]
        return np.unique(np.concatenate(ids)) if ids else np.zeros(0, dtype=np.int64)


@dataclass(frozen=True)
class Body:
    name: str
    kind: Literal["link", "object"]
    index: int  # link index, or index in cell.objects
    mesh: BodyMesh
    tree: OBBTree
    #: the body's shapes as certified closed convex pieces (distances by GJK), or ``None``
    pieces: ConvexPieces | None = None


def _body(name: str, kind: Literal["link", "object"], index: int, mesh: BodyMesh, leaf_size: int) -> Body:
    tree = build_obb_tree(mesh.vertices, mesh.faces, leaf_size)
    return Body(name, kind, index, mesh, tree, cached_convex_pieces(mesh.vertices, mesh.faces, mesh.shape_faces))


def _pack_pieces(bodies: list[Body]) -> tuple[np.ndarray, ...]:
    """The bodies' convex pieces in flat arrays (global vertex and piece indices): per body its
    first piece and piece count (0: no certified pieces, the triangle descent answers)."""
    verts: list[np.ndarray] = [np.zeros((0, 3))]
    adj_start: list[np.ndarray] = [np.zeros(1, dtype=np.int64)]
    adj: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
    pstart: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
    pcount: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
    pcenter: list[np.ndarray] = [np.zeros((0, 3))]
    pradius: list[np.ndarray] = [np.zeros(0)]
    body_first = np.zeros(len(bodies), dtype=np.int64)
    body_count = np.zeros(len(bodies), dtype=np.int64)
    n_v = 0
    n_adj = 0
    n_p = 0
    for k, body in enumerate(bodies):
        pc = body.pieces
        if pc is None:
            continue
        verts.append(pc.vertices)
        adj_start.append(pc.adj_start[1:] + n_adj)
        adj.append(pc.adj + n_v)
        pstart.append(pc.start + n_v)
        pcount.append(pc.count)
        pcenter.append(pc.center)
        pradius.append(pc.radius)
        body_first[k] = n_p
        body_count[k] = pc.n_pieces
        n_v += len(pc.vertices)
        n_adj += len(pc.adj)
        n_p += pc.n_pieces
    return (
        np.concatenate(verts), np.concatenate(adj_start), np.concatenate(adj), np.concatenate(pstart),
        np.concatenate(pcount), np.concatenate(pcenter), np.concatenate(pradius), body_first, body_count,
    )


@dataclass(frozen=True)
class PackedScene:
    """All bodies' hierarchies in flat arrays for the compiled kernel (see ``kernels``)."""

    arrays: tuple[np.ndarray, ...]
    max_depth: int

    @classmethod
    def pack(cls, bodies: list[Body]) -> PackedScene:
        trees = [b.tree for b in bodies]
        node_off = np.cumsum([0] + [t.n_nodes for t in trees])
        tri_off = np.cumsum([0] + [len(t.tris) for t in trees])
        hull_off = np.cumsum([0] + [len(t.hull_vertices) for t in trees])

        def shifted(arr: np.ndarray, off: int) -> np.ndarray:
            return np.where(arr >= 0, arr + off, -1)

        nc = np.concatenate([t.center for t in trees])
        nax = np.concatenate([t.axes for t in trees])
        nh = np.concatenate([t.half for t in trees])
        nrad = np.concatenate([t.radius for t in trees])
        nl = np.concatenate([shifted(t.left, node_off[k]) for k, t in enumerate(trees)])
        nr = np.concatenate([shifted(t.right, node_off[k]) for k, t in enumerate(trees)])
        nts = np.concatenate([shifted(t.tri_start, tri_off[k]) for k, t in enumerate(trees)])
        ntc = np.concatenate([t.tri_count for t in trees])
        tv = np.concatenate([t.tris for t in trees])
        tid = np.concatenate([t.tri_ids for t in trees])
        broot = node_off[:-1].astype(np.int64)
        bsc = np.array([t.sphere_center for t in trees])
        bsr = np.array([t.sphere_radius for t in trees])
        hv = np.concatenate([t.hull_vertices for t in trees])
        hs = hull_off[:-1].astype(np.int64)
        hn = np.array([len(t.hull_vertices) for t in trees], dtype=np.int64)
        rss = swept_rectangles(nax, nh)
        arrays = tuple(
            _frozen(np.ascontiguousarray(a))
            for a in (nc, nax, nh, nrad, nl, nr, nts, ntc, tv, tid, broot, bsc, bsr, hv, hs, hn, rss,
                      *_pack_pieces(bodies))
        )
        return cls(arrays, max(t.depth for t in trees))


@functools.lru_cache(maxsize=16)
def _link_bodies(robot, leaf_size: int) -> tuple[Body, ...]:
    """The robot's link hierarchies, built once per robot model (robots are immutable and
    cached by the loader) and shared by every scene that holds the robot."""
    bodies = []
    for link in range(robot.dof + 1):
        mesh = body_mesh(f"link{link}", robot.shapes.get(link, ()))
        if mesh is not None:
            bodies.append(_body(f"link{link}", "link", link, mesh, leaf_size))
    return tuple(bodies)


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


class SceneData:
    """One caller's working state for ``SceneModel.check`` (not shared between threads).

    The coherence state lives in two flat buffers handed to the compiled check as they are
    (``kernels.check_packed``); ``lb``, ``wit``, ``R_prev``, ``t_prev`` and ``stats`` are views
    of them."""

    def __init__(self, model: SceneModel) -> None:
        n_b, n_p = len(model.bodies), len(model.pair_names)
        self.robot_data = model.robot.new_data() if model.robot is not None else None
        self.sf = np.zeros(n_p + 9 * n_b + 3 * n_b + 16 * n_b)
        self.si = np.zeros(2 * n_p + kernels.N_STATS + 1, dtype=np.int64)
        self.lb = self.sf[:n_p]
        self.R_prev = self.sf[n_p:n_p + 9 * n_b].reshape(n_b, 3, 3)
        self.t_prev = self.sf[n_p + 9 * n_b:n_p + 12 * n_b].reshape(n_b, 3)
        self.wit = self.si[:2 * n_p].reshape(n_p, 2)
        self.stats = self.si[2 * n_p:2 * n_p + kernels.N_STATS]
        self.wit[:] = -1
        self.out = np.empty((3, _INITIAL_TRI_CAPACITY), dtype=np.int64)
        self.mode_cache: dict[object, np.ndarray] = {}

    @property
    def have_prev(self) -> bool:
        return bool(self.si[-1])

    @have_prev.setter
    def have_prev(self, value: bool) -> None:
        self.si[-1] = int(bool(value))

    def reset(self) -> None:
        """Forget coherence (the next check starts cold)."""
        self.have_prev = False
        self.lb[:] = 0.0
        self.wit[:] = -1


class SceneModel:
    """Immutable collision model of a robot and a set of rigid objects."""

    def __init__(
        self,
        bodies: list[Body],
        pairs: list[tuple[int, int]],
        robot=None,
        world_T_base: np.ndarray | None = None,
        object_poses: Mapping[str, np.ndarray] | None = None,
        resting: Iterable[tuple[str, str]] = (),
        source: str = "",
    ) -> None:
        if not bodies:
            raise InputError("a collision scene needs at least one body with geometry")
        self.bodies = tuple(bodies)
        self.body_names = tuple(b.name for b in bodies)
        self._index = {n: i for i, n in enumerate(self.body_names)}
        self.pairs = _frozen(np.array(pairs, dtype=np.int64).reshape(-1, 2))
        self.pair_names = tuple((self.body_names[a], self.body_names[b]) for a, b in pairs)
        self._pair_index = {frozenset(n): p for p, n in enumerate(self.pair_names)}
        self.robot = robot
        self.world_T_base = np.eye(4) if world_T_base is None else np.array(world_T_base, dtype=float)
        self.link_bodies = tuple(i for i, b in enumerate(bodies) if b.kind == "link")
        self.link_indices = np.array([b.index for b in bodies if b.kind == "link"], dtype=np.int64)
        self.object_bodies = tuple(i for i, b in enumerate(bodies) if b.kind == "object")
        self.default_object_poses = {k: np.array(v, dtype=float) for k, v in (object_poses or {}).items()}
        self.resting_pairs = frozenset(frozenset(r) for r in resting)
        self.source = source
        self.packed = PackedScene.pack(list(bodies))
        self._mf, self._mi = self._buffers()
        self._n_pairs = len(self.pair_names)
        self._chained = bool(self.link_bodies) and self._chain is not None
        self._local = threading.local()
        self._base_mode = np.ones(len(pairs), dtype=np.int8)

    # -- construction --------------------------------------------------------------------------
    @classmethod
    def from_cell(
        cls, cell, leaf_size: int = 1, object_pairs: Literal["none", "movable", "all"] = "movable",
        exclude: Iterable[str] = (),
    ) -> SceneModel:
        """Build the hierarchies of the cell's robot links and objects (once). ``exclude``: names
        of objects left out, because a dedicated checker handles them (a terrain of tens of
        thousands of triangles has its own tree in ``shared.terrain``)."""
        if object_pairs not in ("none", "movable", "all"):
            raise InputError(f"object_pairs must be one of 'none', 'movable', 'all', got {object_pairs!r}")
        excluded = set(exclude)
        unknown = excluded - {o.name for o in cell.objects}
        if unknown:
            raise UnknownNameError("object to exclude", sorted(unknown)[0], [o.name for o in cell.objects])
        robot = cell.robot
        bodies: list[Body] = list(_link_bodies(robot, leaf_size))
        for k, obj in enumerate(cell.objects):
            if obj.name in excluded:
                continue
            mesh = body_mesh(obj.name, obj.shapes)
            if mesh is not None:
                bodies.append(_body(obj.name, "object", k, mesh, leaf_size))
        skip = {frozenset((i, i + 1)) for i in range(robot.dof)}
        skip |= {frozenset(p) for p in robot.description.always_in_contact}
        pairs: list[tuple[int, int]] = []
        object_pair_ids: list[int] = []
        for i, bi in enumerate(bodies):
            for j in range(i + 1, len(bodies)):
                bj = bodies[j]
                if bi.kind == "link" and bj.kind == "link":
                    if frozenset((bi.index, bj.index)) in skip:
                        continue
                elif bi.kind == "object" and bj.kind == "object":
                    oi, oj = cell.objects[bi.index], cell.objects[bj.index]
                    if object_pairs == "none" or (object_pairs == "movable" and not (oi.movable or oj.movable)):
                        continue
                    object_pair_ids.append(len(pairs))
                pairs.append((i, j))
        poses = {o.name: o.world_T_object for o in cell.objects}
        model = cls(bodies, pairs, robot, cell.world_T_base, poses, source=cell.source)
        if object_pair_ids:  # find the resting contacts in the cell as loaded
            mode = np.zeros(len(pairs), dtype=np.int8)
            mode[object_pair_ids] = 1
            mode.flags.writeable = False  # as every mode the checks pass: one compiled signature
            raw = model._run(model._world_poses(cell.q_home, None), mode, model.new_data(), first_only=True)
            resting = [model.pair_names[p] for p in object_pair_ids if raw[0][p]]
            model.resting_pairs = frozenset(frozenset(r) for r in resting)
        return model

    @classmethod
    def from_robot(cls, robot, leaf_size: int = 1, skip: Iterable[tuple[int, int]] = ()) -> SceneModel:
        """The robot alone, for self-collision (mechanical interference zones): its links at
        ``world_T_base = I``; pairs are non-adjacent links not declared always in contact and
        not in ``skip`` (link index pairs)."""
        bodies = list(_link_bodies(robot, leaf_size))
        excluded = {frozenset((i, i + 1)) for i in range(robot.dof)}
        excluded |= {frozenset(p) for p in robot.description.always_in_contact}
        excluded |= {frozenset(p) for p in skip}
        pairs = [
            (i, j)
            for i in range(len(bodies))
            for j in range(i + 1, len(bodies))
            if frozenset((bodies[i].index, bodies[j].index)) not in excluded
        ]
        return cls(bodies, pairs, robot, np.eye(4), {}, source=robot.description.source)

    # -- per-caller state ----------------------------------------------------------------------
    def new_data(self) -> SceneData:
        return SceneData(self)

    def _data(self, data: SceneData | None) -> SceneData:
        if data is not None:
            return data
        cached = getattr(self._local, "data", None)
        if cached is None:
            cached = self._local.data = self.new_data()
        return cached

    # -- names -----------------------------------------------------------------------------------
    def body(self, name: str) -> Body:
        try:
            return self.bodies[self._index[name]]
        except KeyError:
            raise UnknownNameError("body", name, self.body_names) from None

    def mesh(self, name: str) -> BodyMesh:
        """The body's mesh in its own frame; reported triangle ids index ``mesh.faces``."""
        return self.body(name).mesh

    def pair_index(self, a: str, b: str) -> int:
        for n in (a, b):
            if n not in self._index:
                raise UnknownNameError("body", n, self.body_names)
        try:
            return self._pair_index[frozenset((a, b))]
        except KeyError:
            raise UnknownNameError("checked pair", f"{a}/{b}", [f"{x}/{y}" for x, y in self.pair_names]) from None

    # -- poses -----------------------------------------------------------------------------------
    @cached_property
    def _template_poses(self) -> np.ndarray:
        """Every body's world pose with the objects where the cell puts them (links: identity)."""
        out = np.tile(np.eye(4), (len(self.bodies), 1, 1))
        for i in self.object_bodies:
            out[i] = self.default_object_poses.get(self.bodies[i].name, np.eye(4))
        return out

    @cached_property
    def _link_body_list(self) -> list[int]:
        return list(self.link_bodies)

    @cached_property
    def _chain(self) -> tuple[np.ndarray, ...] | None:
        """Arrays for ``kernels.chain_link_poses`` when the robot is a serial chain of revolute
        joints about local z (every DH robot): link poses then cost one compiled call rather
        than pinocchio's frame loop and a stack of 4x4 copies. ``None``: use the robot's
        ``link_poses``."""
        robot = self.robot
        if robot is None or not self.link_bodies:
            return None
        try:
            import pinocchio as pin

            model = robot.model
            signs = []
            placements = []
            for j in range(1, model.njoints):
                joint = model.joints[j]
                if model.parents[j] != j - 1:
                    return None
                kind = joint.shortname()
                if kind == "JointModelRZ":
                    signs.append(1.0)
                elif kind == "JointModelRevoluteUnaligned":
                    axis = np.asarray(joint.extract().axis, dtype=float)
                    if not np.allclose(np.abs(axis), [0.0, 0.0, 1.0], atol=0.0):
                        return None
                    signs.append(float(np.sign(axis[2])))
                else:
                    return None
                placements.append(model.jointPlacements[j].homogeneous)
            if len(signs) != robot.dof:
                return None
            frames = [model.frames[f] for f in robot.link_frame_ids]
            frame_joint = np.array([f.parentJoint for f in frames], dtype=np.int64)
            frame_T_link = np.array([f.placement.homogeneous for f in frames])
        except (AttributeError, ImportError, TypeError, ValueError):
            return None
        body_of_frame = np.full(len(frames), -1, dtype=np.int64)
        for body, link in zip(self.link_bodies, self.link_indices):
            body_of_frame[link] = body
        del pin
        return (
            np.ascontiguousarray(self.world_T_base, dtype=float),
            np.ascontiguousarray(np.array(placements)),
            np.array(signs),
            frame_joint,
            np.ascontiguousarray(frame_T_link),
            body_of_frame,
        )

    def _buffers(self) -> tuple[np.ndarray, np.ndarray]:
        """The packed arrays and the chain's as the compiled check's two buffers."""
        (nc, nax, nh, nrad, nl, nr, nts, ntc, tv, tid, broot, bsc, bsr, hv, hs, hn, rss,
         cv, cadjs, cadj, cps, cpn, cpc, cpr, cbf, cbn) = self.packed.arrays
        chain = self._chain
        if chain is None:
            chain = (np.eye(4), np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, 4, 4)),
                     np.zeros(0, dtype=np.int64))
        wTb, placements, signs, frame_joint, frame_T_link, body_of_frame = chain
        mf, mi = kernels.pack_buffers(
            [nc, nax, nh, nrad, tv, bsc, bsr, hv, rss, cv, cpc, cpr, wTb, placements, signs, frame_T_link],
            [nl, nr, nts, ntc, tid, broot, hs, hn, cadjs, cadj, cps, cpn, cbf, cbn, self.pairs, frame_joint, body_of_frame],
        )
        return _frozen(mf), _frozen(mi)

    def _placed(self, object_poses: Mapping[str, np.ndarray] | None) -> np.ndarray:
        """The template poses with ``object_poses`` applied (a fresh array if any)."""
        if not object_poses:
            return self._template_poses
        for name in object_poses:
            if name not in self.default_object_poses and name not in self._index:
                raise UnknownNameError("object", name, self.default_object_poses)
        out = self._template_poses.copy()
        for i in self.object_bodies:
            name = self.bodies[i].name
            pose = object_poses.get(name)
            if pose is not None:
                pose = np.asarray(pose, dtype=float)
                if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
                    raise InputError(f"pose of object {name!r} must be a finite (4, 4) transform")
                out[i] = pose
        return out

    def _world_poses(self, q, object_poses: Mapping[str, np.ndarray] | None, data: SceneData | None = None) -> np.ndarray:
        out = self._placed(object_poses).copy()
        if self.link_bodies:
            if q is None:
                raise InputError("a joint vector is needed to place the robot's links")
            q = self.robot.as_q(q)
            chain = self._chain
            if chain is not None:
                wTb, placements, signs, frame_joint, frame_T_link, body_of_frame = chain
                kernels.chain_link_poses(wTb, placements, signs, frame_joint, frame_T_link, q, body_of_frame, out)
            else:
                poses = self.robot.link_poses(q, data.robot_data if data is not None else None)
                out[self._link_body_list] = self.world_T_base @ poses[self.link_indices]
        return out

    def body_poses(self, q, object_poses: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """``world_T_body`` of every body at ``q`` (and the given object poses)."""
        poses = self._world_poses(q, object_poses)
        return {n: poses[i] for i, n in enumerate(self.body_names)}

    # -- pair selection ----------------------------------------------------------------------------
    def _mode(self, data: SceneData, distances: DistanceSelection, skip, moved: frozenset[str]) -> np.ndarray:
        if not skip and not moved and type(distances) is str:  # the common call, looked up at once
            mode = data.mode_cache.get(distances)
            if mode is None:
                mode = data.mode_cache[distances] = self._mode_for(data, distances, skip, moved)
            return mode
        return self._mode_for(data, distances, skip, moved)

    def _mode_for(self, data: SceneData, distances: DistanceSelection, skip, moved: frozenset[str]) -> np.ndarray:
        if isinstance(distances, str):
            if distances not in ("all", "none"):
                raise InputError(f"distances must be 'all', 'none' or a list of body names or pairs, got {distances!r}")
            dkey: object = distances
        elif distances is None or distances is False:
            dkey = "none"
        elif distances is True:
            dkey = "all"
        else:
            dkey = tuple(d if isinstance(d, str) else tuple(d) for d in distances)
        skey = tuple(tuple(s) for s in skip)
        rest = tuple(sorted(n for n in moved if any(n in r for r in self.resting_pairs)))
        key = (dkey, skey, rest)
        mode = data.mode_cache.get(key)
        if mode is not None:
            return mode
        mode = self._base_mode.copy()
        if dkey == "all":
            mode[:] = 2
        elif dkey != "none":
            for item in dkey:
                if isinstance(item, str):
                    self.body(item)
                    for p, (a, b) in enumerate(self.pair_names):
                        if item in (a, b):
                            mode[p] = 2
                else:
                    mode[self.pair_index(*item)] = 2
        for s in skey:
            mode[self.pair_index(*s)] = 0
        for p, names in enumerate(self.pair_names):
            fs = frozenset(names)
            if fs in self.resting_pairs and not (fs & moved):
                mode[p] = 0
        mode.flags.writeable = False
        if len(data.mode_cache) > 64:
            data.mode_cache.clear()
        data.mode_cache[key] = mode
        return mode

    # -- the check -----------------------------------------------------------------------------------
    def _run(self, world: np.ndarray, mode: np.ndarray, data: SceneData, first_only: bool = False, q=None):
        """One compiled check: links placed from ``q`` when given (``world`` then holds the
        objects' poses), else every body at ``world``. Returns (hit, res, n_out): ``res`` per pair
        the distance and the witness points (``kernels.check_packed``)."""
        use_chain = q is not None
        qq = q if use_chain else _NO_Q
        n_p = len(self.pair_names)
        hit = np.empty(n_p, dtype=np.bool_)
        res = np.empty((n_p, 7))
        while True:
            n_out = kernels.check_packed(self._mf, self._mi, qq, world, use_chain, mode, not first_only,
                                         data.sf, data.si, data.out, hit, res)
            if n_out < 0:
                self.robot.as_q(q)  # names what is wrong with it
                raise InputError("joint vector rejected by the collision check")
            if n_out <= data.out.shape[1]:
                return hit, res, n_out
            data.out = np.empty((3, int(2 * n_out)), dtype=np.int64)

    def _q_for_chain(self, q) -> np.ndarray | None:
        """``q`` as the compiled chain takes it (checked there for length and finiteness), or
        ``None`` when the links are placed in Python (no chain, or no links)."""
        if not self.link_bodies or self._chain is None:
            return None
        if q is None:
            raise InputError("a joint vector is needed to place the robot's links")
        if type(q) is np.ndarray and q.dtype == np.float64 and q.ndim == 1 and q.flags.c_contiguous:
            return q
        return self.robot.as_q(q)

    def _check_q(self, q, object_poses, mode: np.ndarray, data: SceneData, first_only: bool):
        qq = self._q_for_chain(q)
        if qq is not None:
            return self._run(self._placed(object_poses), mode, data, first_only, qq)
        return self._run(self._world_poses(q, object_poses, data), mode, data, first_only)

    def check(
        self,
        q,
        *,
        object_poses: Mapping[str, np.ndarray] | None = None,
        distances: DistanceSelection = "all",
        skip: Iterable[tuple[str, str]] = (),
        triangles: bool = True,
        data: SceneData | None = None,
    ) -> CollisionReport:
        """Check the robot at ``q`` (radians) among the objects.

        ``object_poses``: ``world_T_object`` overrides by name (a carried or displaced object).
        ``distances``: ``"all"`` pairs, ``"none"``, or body names (every pair involving them) and
        ``(a, b)`` pairs; distances cost more than the yes/no answer. ``skip``: body pairs to
        leave out of this check (e.g. a held object and the gripper). ``triangles=False`` stops
        at the first interfering triangle pair of each body pair (faster when only the answer
        and the pairs are needed).
        """
        if data is None:
            data = self._data(None)
        if (self._chained and not object_poses and not skip and type(q) is np.ndarray
                and q.dtype == np.float64 and q.ndim == 1 and q.flags.c_contiguous):
            # the display-rate call goes straight to the compiled check: the general path's
            # helper calls cost as much as the kernel's own work on a coherent drag
            mode = self._mode(data, distances, skip, _NOTHING_MOVED)
            return self._report(data, *self._run(self._template_poses, mode, data, not triangles, q), mode)
        moved = frozenset(object_poses) if object_poses else _NOTHING_MOVED
        mode = self._mode(data, distances, skip, moved)
        return self._report(data, *self._check_q(q, object_poses, mode, data, not triangles), mode)

    def pair_hits(self, q, *, data: SceneData | None = None) -> np.ndarray:
        """Which checked pairs interfere at ``q`` (bool per ``pair_names``): the yes/no answer
        without distances, triangle lists or a report, for sampling many configurations."""
        data = self._data(data)
        mode = self._mode(data, "none", (), _NOTHING_MOVED)
        return self._check_q(q, None, mode, data, True)[0]

    def check_world(
        self,
        world_T_body: Mapping[str, np.ndarray] | np.ndarray,
        *,
        distances: DistanceSelection = "all",
        skip: Iterable[tuple[str, str]] = (),
        triangles: bool = True,
        data: SceneData | None = None,
    ) -> CollisionReport:
        """Like ``check`` with every body's world pose given: a ``(n_bodies, 4, 4)`` array in
        ``body_names`` order, or a mapping name -> pose (missing objects at their cell pose)."""
        data = self._data(data)
        if isinstance(world_T_body, Mapping):
            world = self._world_poses(None, None) if not self.link_bodies else np.empty((len(self.bodies), 4, 4))
            missing = [n for n in self.body_names if n not in world_T_body and self.bodies[self._index[n]].kind == "link"]
            if missing:
                raise InputError(f"poses missing for bodies {missing}")
            for i, n in enumerate(self.body_names):
                if n in world_T_body:
                    world[i] = world_T_body[n]
                else:
                    world[i] = self.default_object_poses.get(n, np.eye(4))
            moved = frozenset(n for n in world_T_body if self.bodies[self._index[n]].kind == "object")
        else:
            world = np.array(world_T_body, dtype=float, order="C")
            if world.shape != (len(self.bodies), 4, 4):
                raise InputError(f"expected ({len(self.bodies)}, 4, 4) poses, got {world.shape}")
            moved = frozenset(self.body_names[i] for i in self.object_bodies)
        if not np.all(np.isfinite(world)):
            raise InputError("body poses must be finite (a NaN or infinity was given)")
        mode = self._mode(data, distances, skip, moved)
        return self._report(data, *self._run(world, mode, data, first_only=not triangles), mode)

    def _report(self, data: SceneData, hit, res, n_out, mode) -> CollisionReport:
        tris = None
        if n_out:  # the buffers are the caller's and the next check overwrites them
            tris = (data.out[0, :n_out].copy(), data.out[1, :n_out].copy(), data.out[2, :n_out].copy())
        return CollisionReport(self.pair_names, hit, res, mode, tris)
