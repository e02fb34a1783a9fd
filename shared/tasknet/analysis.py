"""Behaviour of a P/T net: reachability graph (with a states cap), Karp-Miller coverability,
and the properties the thesis relies on (boundedness, safeness, liveness, terminal markings).

Terminal markings are Definition 3.14's: reachable markings at which no transition is enabled
(dead markings, deadlocks). Liveness is L4-liveness: from every reachable marking, each
transition can still be made to fire. On a finite reachability graph that holds for ``t`` iff
every bottom strongly connected component contains an edge labelled ``t``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from shared.errors import TeleprogError
from shared.tasknet.ptnet import PTNet

DEFAULT_STATES_CAP = 100_000
COVERABILITY_CAP = 20_000
"""The most Karp-Miller nodes ``check_net`` builds when reachability stopped at its cap (each
node compares itself with all its ancestors, so the tree costs more per node than the graph)."""
OMEGA = -1
"""How an omega entry (unboundedly many tokens) is written in a coverability marking."""


class StateSpaceTooLarge(TeleprogError):
    """A search met its states cap before it finished."""


@dataclass(frozen=True)
class ReachabilityGraph:
    """Markings reached from M0 breadth-first, and the firings between them.

    ``markings[0]`` is M0. ``edges`` is ``(k, 3)``: source index, transition index, target index.
    When the cap was met, ``complete`` is False: the graph holds ``cap`` markings and
    ``frontier`` the indices of markings whose successors were not all explored."""

    net: PTNet
    markings: np.ndarray
    edges: np.ndarray
    complete: bool
    cap: int
    frontier: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.markings)

    @property
    def dead(self) -> np.ndarray:
        """Indices of explored markings with no enabled transition (Definition 3.14)."""
        has_out = np.zeros(len(self.markings), dtype=bool)
        has_out[self.edges[:, 0]] = True
        if len(self.frontier):
            has_out[self.frontier] = True  # not known to be dead
        return np.flatnonzero(~has_out)

    def marking_set(self) -> set[tuple[int, ...]]:
        return {tuple(int(x) for x in m) for m in self.markings}


def reachability_graph(net: PTNet, cap: int = DEFAULT_STATES_CAP, strict: bool = False) -> ReachabilityGraph:
    """Breadth-first reachability from M0, stopping at ``cap`` markings (``strict``: raise then)."""
    if cap < 1:
        raise TeleprogError(f"the states cap must be at least 1; got {cap}")
    index: dict[bytes, int] = {net.m0.tobytes(): 0}
    markings = [np.array(net.m0)]
    edges: list[np.ndarray] = []
    queue: deque[int] = deque([0])
    complete = True
    while queue:
        i = queue[0]
        ts, nexts = net.successors(markings[i])
        targets = np.empty(len(ts), dtype=np.int64)
        for k, m in enumerate(nexts):
            key = m.tobytes()
            j = index.get(key)
            if j is None:
                if len(markings) >= cap:
                    complete = False
                    break
                j = index[key] = len(markings)
                markings.append(m)
                queue.append(j)
            targets[k] = j
        else:
            queue.popleft()
            if len(ts):
                edges.append(np.column_stack([np.full(len(ts), i), ts, targets]))
            continue
        break
    if not complete and strict:
        raise StateSpaceTooLarge(f"net {net.id!r}: more than {cap} reachable markings (raise the states cap)")
    return ReachabilityGraph(
        net=net,
        markings=np.array(markings, dtype=np.int64).reshape(len(markings), len(net.places)),
        edges=np.concatenate(edges) if edges else np.zeros((0, 3), dtype=np.int64),
        complete=complete,
        cap=cap,
        frontier=np.array(list(queue), dtype=np.int64),
    )


_MANY = np.iinfo(np.int64).max // 2

# -- coverability --------------------------------------------------------------------------


@dataclass(frozen=True)
class CoverabilityTree:
    """The Karp-Miller tree: ``markings`` with OMEGA (-1) where a place is unbounded,
    ``parent`` (-1 at the root) and the transition that led to each node (-1 at the root)."""

    net: PTNet
    markings: np.ndarray
    parent: np.ndarray
    via: np.ndarray

    def bounds(self) -> np.ndarray:
        """The k-bound of each place; OMEGA where the place is unbounded."""
        m = self.markings
        return np.where((m == OMEGA).any(axis=0), OMEGA, m.max(axis=0))

    def covers(self, m: np.ndarray) -> bool:
        """Whether some node covers ``m`` (every reachable marking is covered)."""
        return bool(((self.markings == OMEGA) | (self.markings >= np.asarray(m)[None, :])).all(axis=1).any())

    def quasi_live(self) -> np.ndarray:
        """``(n_transitions,)`` bool: transitions enabled at some node, i.e. that fire from M0 at least once."""
        seen = self.via[self.via >= 0]
        out = np.zeros(len(self.net.transitions), dtype=bool)
        out[seen] = True
        return out


def coverability_tree(net: PTNet, cap: int = DEFAULT_STATES_CAP) -> CoverabilityTree:
    """Karp-Miller: expand breadth-first; a new marking that strictly covers an ancestor gets
    omega wherever it grew; a marking already in the tree is not expanded again.

    A net with capacities is analysed through ``net.without_capacities()`` (Karp-Miller needs
    monotone firing) and the result is given on the net's own places."""
    base = net.without_capacities()
    c = base.incidence
    n_orig = len(net.places)
    markings = [np.array(base.m0)]
    parent = [-1]
    via = [-1]
    # per node: its finite token total and its number of omega places, for a cheap pre-test
    # (a child without omega can only strictly cover an ancestor without omega and with fewer
    # tokens), so bounded and conservative nets skip the comparison with all ancestors
    tot = np.zeros(cap + 1, dtype=np.int64)
    nom = np.zeros(cap + 1, dtype=np.int64)
    tot[0] = int(base.m0.sum())
    chains: dict[int, np.ndarray] = {0: np.array([0], dtype=np.int64)}  # ancestors of queued nodes, self included
    seen: set[bytes] = {markings[0].tobytes()}
    queue: deque[int] = deque([0])
    while queue:
        i = queue.popleft()
        m = markings[i]
        chain = chains.pop(i)
        omega = m == OMEGA
        enabled = base.enabled(np.where(omega, _MANY, m))  # omega covers any weight
        ancestors = anc_omega = None
        for t in np.flatnonzero(enabled):
            child = np.where(omega, OMEGA, m + c[:, t])
            child_omega = child == OMEGA
            if child_omega.any():
                candidates = True
            else:
                candidates = bool(((nom[chain] == 0) & (tot[chain] < child.sum())).any())
            if candidates:
                # acceleration: a strictly covered ancestor turns every grown place into omega
                if ancestors is None:
                    ancestors = np.array([markings[a] for a in chain])
                    anc_omega = ancestors == OMEGA
                le = (child_omega[None, :] | (~anc_omega & (ancestors <= child[None, :]))).all(axis=1)
                grown = ~anc_omega & ~child_omega[None, :] & (ancestors < child[None, :])
                strict = le & grown.any(axis=1)
                if strict.any():
                    child = np.where(grown[strict].any(axis=0), OMEGA, child)
                    child_omega = child == OMEGA
            if len(markings) >= cap:
                raise StateSpaceTooLarge(f"net {net.id!r}: the coverability tree has more than {cap} nodes")
            k = len(markings)
            markings.append(child)
            parent.append(i)
            via.append(int(t))
            tot[k] = int(child[~child_omega].sum())
            nom[k] = int(child_omega.sum())
            key = child.tobytes()
            if key not in seen:
                seen.add(key)
                queue.append(k)
                chains[k] = np.append(chain, k)
    arr = np.array(markings, dtype=np.int64)[:, :n_orig]
    return CoverabilityTree(net=net, markings=arr, parent=np.array(parent), via=np.array(via))


# -- properties ----------------------------------------------------------------------------


def live_transitions(graph: ReachabilityGraph) -> np.ndarray:
    """L4-liveness per transition on a complete reachability graph: ``(n_transitions,)`` bool."""
    if not graph.complete:
        raise StateSpaceTooLarge(
            f"net {graph.net.id!r}: liveness needs the whole reachability graph; it has more than {graph.cap} markings"
        )
    n = len(graph.markings)
    src, t, dst = graph.edges.T if len(graph.edges) else (np.zeros(0, int),) * 3
    adj = csr_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(n, n))
    _, comp = connected_components(adj, directed=True, connection="strong")
    crossing = comp[src] != comp[dst]
    bottom = np.ones(comp.max() + 1, dtype=bool)
    bottom[comp[src[crossing]]] = False
    n_t = len(graph.net.transitions)
    # which transitions label an edge inside each bottom component
    inside = (comp[src] == comp[dst]) & bottom[comp[src]]
    has = np.zeros((comp.max() + 1, n_t), dtype=bool)
    has[comp[src[inside]], t[inside]] = True
    return has[bottom].all(axis=0)


@dataclass(frozen=True)
class NetReport:
    """What ``teleprog net check`` says about a net; None where it could not be decided
    within the states cap."""

    places: int
    transitions: int
    arcs: int
    reachable_markings: int
    reachability_complete: bool
    states_cap: int
    bounded: bool | None
    bounds: dict[str, int | None] | None
    safe: bool | None
    deadlock_free: bool | None
    dead_markings: list[dict[str, int]]
    live: bool | None
    live_transitions: dict[str, bool] | None
    quasi_live_transitions: dict[str, bool] | None
    notes: list[str]

    def as_json(self) -> dict:
        return dict(self.__dict__)


def check_net(net: PTNet, cap: int = DEFAULT_STATES_CAP, max_dead_listed: int = 10) -> NetReport:
    """Boundedness, safeness, liveness and terminal markings of a net, exact when its
    reachability graph fits in ``cap`` markings, from Karp-Miller otherwise."""
    graph = reachability_graph(net, cap)
    ids_p = [p.id for p in net.places]
    ids_t = [t.id for t in net.transitions]
    notes: list[str] = []
    dead = graph.dead
    dead_list = [net.marking_dict(graph.markings[i]) for i in dead[:max_dead_listed]]
    if graph.complete:
        bound_vec = graph.markings.max(axis=0) if len(net.places) else np.zeros(0, dtype=np.int64)
        bounds: dict[str, int | None] | None = {p: int(b) for p, b in zip(ids_p, bound_vec)}
        bounded: bool | None = True
        live_vec = live_transitions(graph)
        live_map: dict[str, bool] | None = {t: bool(v) for t, v in zip(ids_t, live_vec)}
        fired = np.zeros(len(ids_t), dtype=bool)
        fired[graph.edges[:, 1]] = True
        quasi: dict[str, bool] | None = {t: bool(v) for t, v in zip(ids_t, fired)}
        deadlock_free: bool | None = len(dead) == 0
    else:
        notes.append(f"more than {cap} reachable markings: reachability stopped at the states cap")
        live_map = None
        deadlock_free = False if len(dead) else None
        try:
            tree = coverability_tree(net, min(cap, COVERABILITY_CAP))
        except StateSpaceTooLarge as exc:
            notes.append(str(exc))
            bounds, bounded, quasi = None, None, None
        else:
            b = tree.bounds()
            bounds = {p: (None if v == OMEGA else int(v)) for p, v in zip(ids_p, b)}
            bounded = bool((b != OMEGA).all())
            quasi = {t: bool(v) for t, v in zip(ids_t, tree.quasi_live())}
            if not bounded:
                notes.append("unbounded places (bound null): " + ", ".join(p for p, v in bounds.items() if v is None))
    safe = None if bounds is None else all(v is not None and v <= 1 for v in bounds.values())
    if bounded is False:
        safe = False
    live = None if live_map is None else all(live_map.values())
    if live is None and quasi is not None and not all(quasi.values()):
        live = False  # a transition that never fires is not live
        notes.append("not live: some transitions never fire (from the coverability tree)")
    return NetReport(
        places=len(ids_p),
        transitions=len(ids_t),
        arcs=len(net.arcs),
        reachable_markings=len(graph),
        reachability_complete=graph.complete,
        states_cap=cap,
        bounded=bounded,
        bounds=bounds,
        safe=safe,
        deadlock_free=deadlock_free,
        dead_markings=dead_list,
        live=live,
        live_transitions=live_map,
        quasi_live_transitions=quasi,
        notes=notes,
    )
