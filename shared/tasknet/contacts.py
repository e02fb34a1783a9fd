"""State recognition (§3.5.3): which atoms of the task space hold in a state of the cell, decided
by contacts between feature faces (Definition 3.26's predicate conditions).

Each individual carries rectangles (its feature faces) fixed in its own frame: the hand's in the
tool centre point's frame (one set with the gripper open, one closed), an object's in the
object's frame, a feature's in the feature's frame. A predicate's condition is a conjunction of
sub-conditions ``C_i = ∃(u, v) Contact(f_u, f_v)`` that must hold (``present``) or must not
(``absent``); two faces are in contact when the collision core's exact distance between them
(``shared.collision.distance.quad_pair_distances``) is within the task's contact tolerance.

:meth:`ContactModel.evaluate` decides only the atoms it is asked for, in one batch of face
pairs: the coordinator asks for the atoms the enabled transitions can change, the context
restriction of §3.5.3.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from shared.cells.object_world import ObjectWorld
from shared.collision.distance import quad_pair_distances
from shared.errors import InputError
from shared.tasknet.taskspace import FaceSpec, KindSpec, TaskSpace

MM = 1e-3


@dataclass(frozen=True)
class CellState:
    """What recognition reads from one side's cell (virtual or remote) at one moment: the tool
    centre point, whether the gripper is closed, and where the movable objects are (m)."""

    world_T_tcp: np.ndarray
    gripper_closed: bool
    world_T_objects: Mapping[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def of_world(cls, world: ObjectWorld, world_T_tcp: np.ndarray) -> "CellState":
        """The state of an object world with the tool at ``world_T_tcp``: the gripper is closed
        while it holds an object."""
        poses = {name: world.world_T_object(name, world_T_tcp) for name in world.cell.object_names}
        return cls(np.asarray(world.tool_pose(world_T_tcp), dtype=float), world.held is not None, poses)


def _corners(faces: list[FaceSpec]) -> np.ndarray:
    """(n, 4, 4) homogeneous corners (m) of rectangles, in order round the edge."""
    out = np.ones((len(faces), 4, 4))
    for i, f in enumerate(faces):
        c, u, v = (np.asarray(x, dtype=float) * MM for x in (f.centre, f.u, f.v))
        out[i, :, :3] = [c - u - v, c + u - v, c + u + v, c - u + v]
    return out


@dataclass(frozen=True)
class _Term:
    """One side of a sub-condition: individuals (one, or every one of a kind) and face indices."""

    who: tuple[str, ...]
    faces: tuple[int, ...]


@dataclass(frozen=True)
class _Clause:
    holds: bool  # True: some pair must touch; False: no pair may
    a: _Term
    b: _Term


class ContactModel:
    """The feature faces of a task space's individuals placed in a cell, and the predicate
    conditions compiled to face pairs."""

    def __init__(self, space: TaskSpace, cell) -> None:
        self.space = space
        self.cell = cell
        spec = space.spec
        self.tolerance = spec.contact_tolerance_mm * MM
        self._kind_of = {name: ind.kind for name, ind in spec.individuals.items()}
        self._face_names: dict[str, list[str]] = {}
        self._local: dict[str, np.ndarray] = {}  # kind -> corners; the hand: "hand/open", "hand/closed"
        for kind, ks in spec.kinds.items():
            self._face_names[kind] = self._kind_faces(kind, ks)
            if ks.faces_open or ks.faces_closed:
                self._local[f"{kind}/open"] = _corners(ks.faces_open)
                self._local[f"{kind}/closed"] = _corners(ks.faces_closed)
            else:
                self._local[kind] = _corners(ks.faces)
        self._fixed: dict[str, np.ndarray] = {}  # feature individuals: world corners, once
        self._object_of: dict[str, str] = {}
        for name, ind in spec.individuals.items():
            if ind.feature is not None:
                if ind.feature not in cell.features:
                    raise InputError(f"{space.source}: individual {name!r} is feature {ind.feature!r}, which cell {cell.name!r} does not have")
                world_T_f = np.asarray(cell.features[ind.feature].world_T_feature, dtype=float)
                self._fixed[name] = np.einsum("ij,fkj->fki", world_T_f, self._local[ind.kind])[..., :3]
            elif ind.object is not None:
                if ind.object not in cell.object_names:
                    raise InputError(f"{space.source}: individual {name!r} is object {ind.object!r}, which cell {cell.name!r} does not have")
                self._object_of[name] = ind.object
        self._conditions: dict[str, tuple[_Clause, ...]] = {
            atom.text: self._compile(atom.predicate, atom.args) for atom in space.atoms
        }
        self._plans: dict[tuple[tuple[str, ...], tuple[str, ...]], _Plan] = {}
        self._kept: dict[tuple[tuple[str, ...], tuple[str, ...]], _Kept] = {}  # the last measurement per key
        self._reach = {k: float(np.max(np.linalg.norm(corners[..., :3], axis=-1))) for k, corners in self._local.items()}
        """Farthest corner from its individual's frame origin (m), per set of local corners."""
        self.pairs_checked = 0
        """Face pairs measured so far (the work state recognition has done)."""

    @staticmethod
    def _kind_faces(kind: str, ks: KindSpec) -> list[str]:
        if ks.faces_open or ks.faces_closed:
            a, b = [f.name for f in ks.faces_open], [f.name for f in ks.faces_closed]
            if a != b:
                raise InputError(f"kind {kind!r}: faces_open and faces_closed must name the same faces in the same order")
            return a
        return [f.name for f in ks.faces]

    def _term(self, text: str, binding: dict[str, str], where: str) -> _Term:
        who, sep, faces = text.partition(":")
        if not sep:
            raise InputError(f"{where}: term {text!r} must be WHO:FACES")
        who = who.strip()
        if who.startswith("any "):
            kind = who[4:].strip()
            names = tuple(n for n, k in self._kind_of.items() if k == kind)
            if not names:
                raise InputError(f"{where}: {text!r}: no individual is of kind {kind!r}")
        else:
            name = binding.get(who, who)
            if name not in self._kind_of:
                raise InputError(f"{where}: {text!r} names {who!r}, neither a parameter nor an individual")
            kind, names = self._kind_of[name], (name,)
        all_faces = self._face_names[kind]
        faces = faces.strip()
        groups = self.space.spec.kinds[kind].groups
        chosen = all_faces if faces == "faces" else groups.get(faces, [faces])
        missing = [f for f in chosen if f not in all_faces]
        if missing:
            raise InputError(f"{where}: {text!r}: kind {kind!r} has no face or group {missing[0]!r}")
        return _Term(names, tuple(all_faces.index(f) for f in chosen))

    def _compile(self, predicate: str, args: tuple[str, ...]) -> tuple[_Clause, ...]:
        spec = next(p for p in self.space.spec.predicates if p.name == predicate)
        binding = dict(zip(spec.params, args))
        where = f"{self.space.source}: predicate {predicate}"
        clauses = [_Clause(True, self._term(a, binding, where), self._term(b, binding, where)) for a, b in spec.present]
        clauses += [_Clause(False, self._term(a, binding, where), self._term(b, binding, where)) for a, b in spec.absent]
        return tuple(clauses)

    # -- evaluation -----------------------------------------------------------------------------------
    def forget(self) -> None:
        """Measure afresh on the next :meth:`evaluate` (no kept truth)."""
        self._kept.clear()

    def _placements(self, state: CellState) -> dict[str, tuple[np.ndarray, str]]:
        """Each movable individual present in ``state``: its frame in the world and the key of
        its local corners (the hand's open or closed faces)."""
        out: dict[str, tuple[np.ndarray, str]] = {}
        for name, kind in self._kind_of.items():
            if name in self._fixed:
                continue
            if name in self._object_of:
                obj = self._object_of[name]
                if obj in state.world_T_objects:
                    out[name] = (np.asarray(state.world_T_objects[obj], dtype=float), kind)
            elif f"{kind}/open" in self._local:  # the hand, at the tool centre point
                out[name] = (np.asarray(state.world_T_tcp, dtype=float), f"{kind}/closed" if state.gripper_closed else f"{kind}/open")
        return out

    def evaluate(self, state: CellState, atoms: Iterable[str] | None = None) -> dict[str, bool]:
        """The truth of ``atoms`` (all of the task space's when None) in ``state``.

        Exact, and measured only when it could have changed: the last measurement of the same
        atoms keeps its smallest distance from any face-pair block's minimum gap to the contact
        tolerance (the margin); a face's points move by at most ``|dR|_F r + |dt|`` when its
        individual's frame moves by ``(dR, dt)`` (``r``: its farthest corner), a gap by at most
        the two faces' moves together, so while twice the largest move since then stays under
        the margin no block can cross the tolerance and the kept truth is the truth."""
        wanted = tuple(self._conditions) if atoms is None else tuple(dict.fromkeys(atoms))
        placed = self._placements(state)
        present = tuple(name for name in self._kind_of if name in self._fixed or name in placed)
        key = (wanted, present)
        kept = self._kept.get(key)
        if kept is not None and kept.holds_for(placed, self._reach):
            return dict(kept.truth)
        plan = self._plans.get(key)
        if plan is None:
            plan = self._plans[key] = self._plan(wanted, present)
        margin = np.inf
        if plan.left.size:
            faces = [self._fixed[name] if name in self._fixed else
                     np.einsum("ij,fkj->fki", placed[name][0], self._local[placed[name][1]])[..., :3] for name in present]
            stacked = np.concatenate(faces)
            gaps = quad_pair_distances(stacked[plan.left], stacked[plan.right])
            self.pairs_checked += int(gaps.size)
            block_gap = np.minimum.reduceat(gaps, plan.block_starts)
            touch_block = block_gap <= self.tolerance
            margin = float(np.min(np.abs(block_gap - self.tolerance)))
        else:
            touch_block = np.zeros(0, dtype=bool)
        truth = dict.fromkeys(wanted, True)
        for atom, holds, lo, hi in plan.spans:
            touching = bool(touch_block[lo:hi].any()) if hi > lo else False
            if touching != holds:
                truth[atom] = False
        self._kept[key] = _Kept({name: (world_T.copy(), local) for name, (world_T, local) in placed.items()}, margin, dict(truth))
        return truth

    def _plan(self, wanted: tuple[str, ...], present: tuple[str, ...]) -> "_Plan":
        """The face pairs of ``wanted``'s clauses as indices into the faces of ``present``
        stacked in that order, one block per pair of individuals (built once per key)."""
        offset: dict[str, int] = {}
        n = 0
        for name in present:
            offset[name] = n
            n += self._face_count(name)
        left: list[np.ndarray] = []
        right: list[np.ndarray] = []
        spans: list[tuple[str, bool, int, int]] = []  # atom, holds, first block, end
        for atom in wanted:
            for clause in self._conditions[atom]:
                start = len(left)
                for ia in clause.a.who:
                    for ib in clause.b.who:
                        if ia == ib or ia not in offset or ib not in offset or not clause.a.faces or not clause.b.faces:
                            continue
                        fa = offset[ia] + np.asarray(clause.a.faces, dtype=np.intp)
                        fb = offset[ib] + np.asarray(clause.b.faces, dtype=np.intp)
                        left.append(np.repeat(fa, len(fb)))
                        right.append(np.tile(fb, len(fa)))
                spans.append((atom, clause.holds, start, len(left)))
        sizes = np.array([len(x) for x in left], dtype=np.intp)
        starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.intp) if left else np.zeros(0, dtype=np.intp)
        empty = np.zeros(0, dtype=np.intp)
        return _Plan(
            np.concatenate(left) if left else empty, np.concatenate(right) if right else empty, starts, tuple(spans)
        )

    def _face_count(self, name: str) -> int:
        if name in self._fixed:
            return len(self._fixed[name])
        kind = self._kind_of[name]
        local = self._local.get(kind)
        return len(local if local is not None else self._local[f"{kind}/open"])


@dataclass(frozen=True)
class _Plan:
    """What :meth:`ContactModel.evaluate` measures for one set of atoms and individuals."""

    left: np.ndarray  # face indices into the stacked faces, one row per face pair
    right: np.ndarray
    block_starts: np.ndarray  # the first pair of each pair of individuals (no block is empty)
    spans: tuple[tuple[str, bool, int, int], ...]  # atom, holds, first block, end


@dataclass(frozen=True)
class _Kept:
    """The last measurement of one set of atoms: where the movable individuals were, the margin
    of every face-pair block from the contact tolerance (m), and the truth found."""

    placed: dict[str, tuple[np.ndarray, str]]
    margin: float
    truth: dict[str, bool]

    def holds_for(self, placed: dict[str, tuple[np.ndarray, str]], reach: dict[str, float]) -> bool:
        """Is the kept truth still the truth with the individuals ``placed`` so (see
        :meth:`ContactModel.evaluate`)?"""
        if placed.keys() != self.placed.keys():
            return False
        largest = 0.0
        for name, (world_T, local) in placed.items():
            then, then_local = self.placed[name]
            if local != then_local:
                return False
            d = world_T[:3] - then[:3]
            move = float(np.sqrt(np.dot(d[:, :3].ravel(), d[:, :3].ravel()))) * reach[local] + float(np.sqrt(np.dot(d[:, 3], d[:, 3])))
            if not move < np.inf:  # a NaN or infinite frame: measure
                return False
            largest = max(largest, move)
        return 2.0 * largest < self.margin
