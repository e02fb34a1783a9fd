"""A place/transition net system (thesis Definitions 3.1-3.4) and its firing rule on numpy.

The net is data (pydantic, so it has a JSON form); its matrices are computed once per net:
``pre[s, t] = W(s, t)``, ``post[s, t] = W(t, s)`` and the incidence matrix ``c = post - pre``,
places by transitions. A marking is a ``(n_places,)`` int64 array in the order of ``places``.

Capacities follow Definition 3.4: ``t`` is enabled at ``M`` iff, for every place ``s``,
``W(s, t) <= M(s) <= K(s) - W(t, s)``; a place without a capacity has ``K(s) = omega``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from functools import cached_property

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from shared.errors import InputError, UnknownNameError

NO_CAPACITY = np.iinfo(np.int64).max
"""What the capacity vector holds for a place without a capacity (K = omega)."""

MAX_TOKENS = 10**9
"""Largest initial marking, capacity or arc weight a net may hold (and tokens a marking given by
place may put on one). Markings are int64 arrays: sums and firings of numbers this size stay exact
(a 10**40 would not fit one); no task model needs more than a handful."""


class Place(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    id: str = Field(min_length=1)
    name: str | None = None
    predicate: str | None = None
    """The condition the place stands for in a task model, e.g. ``HOLDING(PEG)``."""
    initial: int = Field(default=0, ge=0, le=MAX_TOKENS)
    """Tokens in the initial marking M0."""
    capacity: int | None = Field(default=None, ge=1, le=MAX_TOKENS)
    """K(s); None is omega (no bound)."""


class Transition(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    id: str = Field(min_length=1)
    name: str | None = None
    action: str | None = None
    """The action the transition stands for in a task model, e.g. ``grasp(PEG)``."""


class Arc(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    source: str = Field(min_length=1)
    target: str = Field(min_length=1)
    weight: int = Field(default=1, ge=1, le=MAX_TOKENS)


class PTNet(BaseModel):
    """A P/T system ``(S, T, F, K, W, M0)``: arcs carry W, places carry K and M0."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    id: str = "net"
    name: str | None = None
    places: tuple[Place, ...]
    transitions: tuple[Transition, ...]
    arcs: tuple[Arc, ...] = ()

    @model_validator(mode="after")
    def _check_structure(self) -> PTNet:
        if not self.places and not self.transitions:
            raise ValueError("a net needs at least one place or transition (S u T is empty)")
        seen: set[str] = set()
        for node in (*self.places, *self.transitions):
            if node.id in seen:
                raise ValueError(f"id {node.id!r} is used twice (places and transitions share one id space)")
            seen.add(node.id)
        place_ids = {p.id for p in self.places}
        transition_ids = {t.id for t in self.transitions}
        pairs: set[tuple[str, str]] = set()
        for arc in self.arcs:
            for end in (arc.source, arc.target):
                if end not in seen:
                    raise ValueError(f"arc {arc.source}->{arc.target}: {end!r} is not a place or transition of the net")
            ok = (arc.source in place_ids and arc.target in transition_ids) or (
                arc.source in transition_ids and arc.target in place_ids
            )
            if not ok:
                raise ValueError(f"arc {arc.source}->{arc.target} must join a place and a transition")
            if (arc.source, arc.target) in pairs:
                raise ValueError(f"arc {arc.source}->{arc.target} is given twice; give one arc with the summed weight")
            pairs.add((arc.source, arc.target))
        for p in self.places:
            if p.capacity is not None and p.initial > p.capacity:
                raise ValueError(f"place {p.id!r}: initial marking {p.initial} exceeds its capacity {p.capacity}")
        return self

    # -- indices and matrices -------------------------------------------------------------

    @cached_property
    def place_index(self) -> dict[str, int]:
        return {p.id: i for i, p in enumerate(self.places)}

    @cached_property
    def transition_index(self) -> dict[str, int]:
        return {t.id: i for i, t in enumerate(self.transitions)}

    @cached_property
    def pre(self) -> np.ndarray:
        """``(n_places, n_transitions)``: W(s, t), the tokens t takes from s."""
        return self._matrix(lambda a: (a.source, a.target) if a.source in self.place_index else None)

    @cached_property
    def post(self) -> np.ndarray:
        """``(n_places, n_transitions)``: W(t, s), the tokens t puts on s."""
        return self._matrix(lambda a: (a.target, a.source) if a.target in self.place_index else None)

    @cached_property
    def incidence(self) -> np.ndarray:
        """C = Post - Pre."""
        c = self.post - self.pre
        c.setflags(write=False)
        return c

    @cached_property
    def m0(self) -> np.ndarray:
        m = np.array([p.initial for p in self.places], dtype=np.int64)
        m.setflags(write=False)
        return m

    @cached_property
    def capacity(self) -> np.ndarray:
        """K per place; NO_CAPACITY where there is none."""
        k = np.array([NO_CAPACITY if p.capacity is None else p.capacity for p in self.places], dtype=np.int64)
        k.setflags(write=False)
        return k

    @cached_property
    def has_capacities(self) -> bool:
        return any(p.capacity is not None for p in self.places)

    def _matrix(self, pick) -> np.ndarray:
        m = np.zeros((len(self.places), len(self.transitions)), dtype=np.int64)
        for arc in self.arcs:
            ends = pick(arc)
            if ends is not None:
                m[self.place_index[ends[0]], self.transition_index[ends[1]]] = arc.weight
        m.setflags(write=False)
        return m

    # -- pre-sets and post-sets (Definition 3.2) -----------------------------------------

    def preset(self, transition: str) -> list[str]:
        j = self.transition_index_of(transition)
        return [self.places[i].id for i in np.flatnonzero(self.pre[:, j])]

    def postset(self, transition: str) -> list[str]:
        j = self.transition_index_of(transition)
        return [self.places[i].id for i in np.flatnonzero(self.post[:, j])]

    def transition_index_of(self, transition: str) -> int:
        try:
            return self.transition_index[transition]
        except KeyError:
            raise UnknownNameError("transition", transition, self.transition_index) from None

    # -- markings -------------------------------------------------------------------------

    def marking(self, tokens: Mapping[str, int] | Iterable[str] | np.ndarray) -> np.ndarray:
        """A marking from ``{place: tokens}``, a collection of marked place ids, or an array."""
        if isinstance(tokens, np.ndarray):
            m = np.asarray(tokens, dtype=np.int64)
            if m.shape != (len(self.places),):
                raise InputError(f"a marking of this net has {len(self.places)} entries; got shape {m.shape}")
            return m
        m = np.zeros(len(self.places), dtype=np.int64)
        items = tokens.items() if isinstance(tokens, Mapping) else ((p, 1) for p in tokens)
        for place, n in items:
            if place not in self.place_index:
                raise UnknownNameError("place", place, self.place_index)
            if n < 0:
                raise InputError(f"place {place!r}: a marking holds no negative tokens; got {n}")
            if n > MAX_TOKENS or m[self.place_index[place]] + n > MAX_TOKENS:
                raise InputError(f"place {place!r}: a marking holds at most {MAX_TOKENS} tokens per place; got {n}")
            m[self.place_index[place]] += n
        return m

    def marking_dict(self, m: np.ndarray) -> dict[str, int]:
        """The non-empty places of a marking by id."""
        return {self.places[i].id: int(m[i]) for i in np.flatnonzero(m)}

    # -- firing (Definition 3.4) -----------------------------------------------------------

    @cached_property
    def _arc_lists(self) -> tuple[np.ndarray, ...]:
        """Pre arcs and capacity-bounded post arcs as flat (place, transition, weight) arrays,
        so enabling costs O(arcs), not O(places x transitions), on large sparse nets."""
        ip, it = np.nonzero(self.pre)
        op, ot = np.nonzero(self.post)
        bounded = self.capacity[op] != NO_CAPACITY
        op, ot = op[bounded], ot[bounded]
        return ip, it, self.pre[ip, it], op, ot, self.capacity[op] - self.post[op, ot]

    def enabled(self, m: np.ndarray) -> np.ndarray:
        """``(n_transitions,)`` bool: which transitions are enabled at the marking ``m``
        (``m <= K``, as every reachable marking is), all at once."""
        m = np.asarray(m, dtype=np.int64)
        ip, it, w, op, ot, room = self._arc_lists
        blocked = np.zeros(len(self.transitions), dtype=bool)
        blocked[it[m[ip] < w]] = True
        blocked[ot[m[op] > room]] = True
        return ~blocked

    def enabled_ids(self, m: np.ndarray) -> list[str]:
        return [self.transitions[j].id for j in np.flatnonzero(self.enabled(m))]

    def successors(self, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every enabled transition's index and the marking it leads to: ``(k,)`` and ``(k, n_places)``."""
        ts = np.flatnonzero(self.enabled(m))
        return ts, np.asarray(m, dtype=np.int64)[None, :] + self.incidence[:, ts].T

    def fire(self, m: np.ndarray, transition: str | int) -> np.ndarray:
        """The marking after firing one transition (by id or index); InputError if it is not enabled."""
        j = self.transition_index_of(transition) if isinstance(transition, str) else int(transition)
        if not self.enabled(m)[j]:
            enabled = self.enabled_ids(m)
            raise InputError(
                f"transition {self.transitions[j].id!r} is not enabled at marking {self.marking_dict(m)}; "
                f"enabled: {', '.join(enabled) or '(none)'}"
            )
        return np.asarray(m, dtype=np.int64) + self.incidence[:, j]

    def fire_sequence(self, m: np.ndarray, sequence: Sequence[str | int]) -> np.ndarray:
        """The marking after firing ``sequence`` in order from ``m``."""
        for t in sequence:
            m = self.fire(m, t)
        return m

    def parikh(self, sequence: Sequence[str | int]) -> np.ndarray:
        """The firing count vector sigma of a sequence: ``(n_transitions,)``."""
        sigma = np.zeros(len(self.transitions), dtype=np.int64)
        for t in sequence:
            sigma[self.transition_index_of(t) if isinstance(t, str) else int(t)] += 1
        return sigma

    def state_equation(self, m: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """M' = M + C sigma: where a sequence with count vector sigma leads, if it can fire."""
        return np.asarray(m, dtype=np.int64) + self.incidence @ np.asarray(sigma, dtype=np.int64)

    # -- transformations ------------------------------------------------------------------

    def without_capacities(self) -> PTNet:
        """The same behaviour with no capacities: each place ``s`` with ``K(s)`` gets a complement
        place ``s~`` holding ``K(s) - M(s)``; ``t`` takes ``W(t, s)`` from it and gives back
        ``W(s, t)``, which is Definition 3.4's ``M(s) <= K(s) - W(t, s)`` as plain enabling.
        The complement places come after the original ones, in the same order."""
        if not self.has_capacities:
            return self
        places = [p.model_copy(update={"capacity": None}) for p in self.places]
        arcs = list(self.arcs)
        taken = {p.id for p in self.places} | {t.id for t in self.transitions}
        for i, p in enumerate(self.places):
            if p.capacity is None:
                continue
            cid = f"{p.id}~"
            while cid in taken:
                cid += "~"
            taken.add(cid)
            places.append(Place(id=cid, name=f"complement of {p.id}", initial=p.capacity - p.initial))
            for j, t in enumerate(self.transitions):
                if self.post[i, j]:
                    arcs.append(Arc(source=cid, target=t.id, weight=int(self.post[i, j])))
                if self.pre[i, j]:
                    arcs.append(Arc(source=t.id, target=cid, weight=int(self.pre[i, j])))
        return PTNet(id=self.id, name=self.name, places=tuple(places), transitions=self.transitions, arcs=tuple(arcs))


def net_from_matrices(
    pre: np.ndarray,
    post: np.ndarray,
    m0: np.ndarray,
    capacity: Sequence[int | None] | None = None,
    net_id: str = "net",
) -> PTNet:
    """A net with places ``p0..`` and transitions ``t0..`` from its Pre and Post matrices."""
    pre = np.asarray(pre, dtype=np.int64)
    post = np.asarray(post, dtype=np.int64)
    if pre.shape != post.shape or pre.ndim != 2 or np.asarray(m0).shape != (pre.shape[0],):
        raise InputError(f"Pre {pre.shape}, Post {post.shape} and M0 {np.asarray(m0).shape} do not fit together")
    n_p, n_t = pre.shape
    caps = list(capacity) if capacity is not None else [None] * n_p
    places = tuple(Place(id=f"p{i}", initial=int(m0[i]), capacity=caps[i]) for i in range(n_p))
    transitions = tuple(Transition(id=f"t{j}") for j in range(n_t))
    arcs = [Arc(source=f"p{i}", target=f"t{j}", weight=int(pre[i, j])) for i, j in zip(*np.nonzero(pre))]
    arcs += [Arc(source=f"t{j}", target=f"p{i}", weight=int(post[i, j])) for i, j in zip(*np.nonzero(post))]
    return PTNet(id=net_id, places=places, transitions=transitions, arcs=tuple(arcs))
