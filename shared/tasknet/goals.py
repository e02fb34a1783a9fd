"""Goals of a task space (issue 40): a set of ground atoms the operator wants to hold, and the
shortest run of actions that gets there from a marking, found on the net's reachability graph.

A goal is written as atoms of the task space (``PEGINHOLE(PEG,HOLE2)``, ``HOLDING(PEG)``). Names
resolve as the task space has them: a predicate in any case, an argument as an individual (in
any case) or as the object or feature of the cell an individual is bound to (``peg`` is ``PEG``).

:func:`plan_goal` grounds the task space's net at the marking, explores its reachability graph
breadth-first (:func:`shared.tasknet.analysis.reachability_graph`, transitions in rule order, so
ties go to the task space's order) and returns the shortest action sequence to a marking where
every goal atom holds. With ``keep`` (the default) the plan disturbs nothing the goal does not
ask to change: each atom of the starting marking that can still hold together with the goal
(and the atoms kept before it) is kept too, so a peg put into a hole is also let go, as the
thesis's transfer ends. A goal no reachable marking meets is one :class:`InputError` naming the
atom that cannot be reached and why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.errors import InputError
from shared.tasknet.analysis import reachability_graph
from shared.tasknet.taskspace import GroundAction, TaskSpace, atom_text, parse_atom

GOAL_STATES_CAP = 100_000
"""The most markings the goal search explores (the shipped task spaces have a few dozen)."""


@dataclass(frozen=True)
class GoalPlan:
    """The shortest action run from ``start`` to a marking where the goal (and ``kept``) holds."""

    goal: tuple[str, ...]
    kept: tuple[str, ...]
    start: tuple[str, ...]
    actions: tuple[GroundAction, ...]
    final: tuple[str, ...]
    states_visited: int

    @property
    def action_texts(self) -> list[str]:
        return [a.text for a in self.actions]


def resolve_argument(space: TaskSpace, name: str) -> str:
    """An atom's argument as the individual it names (exactly, in any case, or by the object or
    feature of the cell the individual is bound to)."""
    inds = space.spec.individuals
    if name in inds:
        return name
    for ind, spec in inds.items():
        if name.lower() in {ind.lower(), (spec.object or "").lower(), (spec.feature or "").lower()}:
            return ind
    raise InputError(f"{name!r} is no individual of the task space {space.spec.name!r}; "
                     f"individuals: {', '.join(inds)}")


def parse_goal(space: TaskSpace, goal: str | list[str] | tuple[str, ...]) -> tuple[str, ...]:
    """The goal's atoms, each as the task space spells it. ``goal`` is a list of atoms or one
    string of atoms separated by ``;`` or by commas outside parentheses."""
    texts = _split(goal) if isinstance(goal, str) else [str(g) for g in goal]
    texts = [t for t in (t.strip() for t in texts) if t]
    if not texts:
        raise InputError("the goal is empty: give at least one atom, e.g. PEGINHOLE(PEG,HOLE2)")
    predicates = {p.name.upper(): p for p in space.spec.predicates}
    known = set(space.atom_texts)
    out: list[str] = []
    for text in texts:
        name, args = parse_atom(text)
        pred = predicates.get(name.upper())
        if pred is None:
            raise InputError(f"goal atom {text!r}: no predicate {name!r} in the task space {space.spec.name!r}; "
                             f"predicates: {', '.join(p.name for p in space.spec.predicates)}")
        if len(args) != len(pred.params):
            raise InputError(f"goal atom {text!r}: {pred.name} takes {len(pred.params)} argument(s), got {len(args)}")
        atom = atom_text(pred.name, tuple(resolve_argument(space, a) for a in args))
        if atom not in known:
            raise InputError(f"goal atom {text!r}: {atom} is not an atom of the task space {space.spec.name!r} "
                             f"(its arguments must be of the kinds {', '.join(pred.params.values())})")
        if atom not in out:
            out.append(atom)
    return tuple(out)


def _split(text: str) -> list[str]:
    parts, depth, cur = [], 0, ""
    for ch in text:
        if ch in ",;" and depth == 0:
            parts.append(cur)
            cur = ""
            continue
        depth += (ch == "(") - (ch == ")")
        cur += ch
    parts.append(cur)
    return parts


def plan_goal(space: TaskSpace, start: frozenset[str] | set[str], goal: str | list[str] | tuple[str, ...],
              keep: bool = True, cap: int = GOAL_STATES_CAP) -> GoalPlan:
    """The shortest action run from the marking ``start`` (its true atoms) to one where every
    atom of ``goal`` holds (and, with ``keep``, every atom of ``start`` that can hold with it)."""
    atoms = parse_goal(space, goal)
    start = frozenset(start)
    unknown = sorted(start - set(space.atom_texts))
    if unknown:
        raise InputError(f"the marking names atoms the task space {space.spec.name!r} does not have: {', '.join(unknown)}")
    graph = reachability_graph(space.net(start), cap=cap)
    index = space.atom_index()
    marks = graph.markings > 0
    order, parent = _feasible_search(graph, marks, placement_groups(space, index))
    if not order:
        raise InputError(f"the marking {{{', '.join(sorted(start))}}} puts one object in two places at once")
    reach = np.zeros(len(marks), dtype=bool)
    reach[order] = True
    ok = reach.copy()
    for k, atom in enumerate(atoms):
        with_it = ok & marks[:, index[atom]]
        if not with_it.any():
            raise InputError(_why_not(space, start, atoms[:k], atom, (reach & marks[:, index[atom]]).any(), graph.complete))
        ok = with_it
    kept: list[str] = []
    if keep:
        for atom in space.atom_texts:
            if atom in start and atom not in atoms:
                with_it = ok & marks[:, index[atom]]
                if with_it.any():
                    ok = with_it
                    kept.append(atom)
    target = next(i for i in order if ok[i])  # breadth-first order: the first is the nearest
    run: list[GroundAction] = []
    node = target
    while node != 0:
        src, t = parent[node]
        run.append(space.action(graph.net.transitions[t].id))
        node = src
    run.reverse()
    final = tuple(a for a, v in zip(space.atom_texts, marks[target]) if v)
    ordered_start = tuple(a for a in space.atom_texts if a in start)
    return GoalPlan(atoms, tuple(kept), ordered_start, tuple(run), final, len(graph))


def enabled_actions(space: TaskSpace, marking: frozenset[str] | set[str]) -> list[GroundAction]:
    """The actions that can fire at ``marking`` (their preconditions hold, not all their results
    hold already, as a C/E net's event), in the task space's order, leaving out any that would put
    an object in two places (``placement_groups``: the goal search skips those markings too)."""
    m = frozenset(marking)
    index = space.atom_index()
    groups = [[space.atom_texts[i] for i in g] for g in placement_groups(space, index)]
    out = []
    for act in space.actions:
        added = [a for a in act.post if a not in act.pre]
        if not all(a in m for a in act.pre) or (added and all(a in m for a in added)):
            continue
        after = (m - set(act.delete)) | set(act.post)
        if any(sum(a in after for a in g) > 1 for g in groups):
            continue
        out.append(act)
    return out


def resolve_action(space: TaskSpace, text: str) -> GroundAction:
    """The action named ``text`` (``grasp(PEG)``; names compare without case, spaces ignored),
    or ``InputError`` listing the task space's actions."""
    want = "".join(text.split()).lower()
    for act in space.actions:
        if act.text.lower() == want:
            return act
    raise InputError(f"the task space {space.spec.name!r} has no action {text.strip()!r}; "
                     f"actions: {', '.join(a.text for a in space.actions)}")


def placement_groups(space: TaskSpace, index: dict[str, int]) -> list[list[int]]:
    """Atoms of which at most one can hold: a predicate relating an individual bound to a cell
    object to one bound to a cell feature (``PEGINHOLE(p, h)``) places the object, and a rigid
    object is at one feature at a time. STRIPS rules need not say so (the thesis's ``mate`` does
    not ask that the peg be out of its hole); the search skips markings that break it."""
    inds = space.spec.individuals
    groups: dict[tuple[str, str], list[int]] = {}
    for atom in space.atoms:
        objs = [i for i, a in enumerate(atom.args) if inds[a].object]
        feats = [i for i, a in enumerate(atom.args) if inds[a].feature]
        if len(atom.args) == 2 and len(objs) == 1 and len(feats) == 1:
            groups.setdefault((atom.predicate, atom.args[objs[0]]), []).append(index[atom.text])
    return [g for g in groups.values() if len(g) > 1]


def _feasible_search(graph, marks: np.ndarray, groups: list[list[int]]) -> tuple[list[int], dict[int, tuple[int, int]]]:
    """Breadth-first over the reachability graph's edges through feasible markings only: the
    markings in the order reached and each one's (parent, transition)."""
    feasible = np.ones(len(marks), dtype=bool)
    for g in groups:
        feasible &= marks[:, g].sum(axis=1) <= 1
    if not feasible[0]:
        return [], {}
    out: dict[int, list[tuple[int, int]]] = {}
    for src, t, dst in graph.edges:
        out.setdefault(int(src), []).append((int(t), int(dst)))
    order, parent, head = [0], {}, 0
    seen = {0}
    while head < len(order):
        node = order[head]
        head += 1
        for t, dst in out.get(node, ()):
            if dst not in seen and feasible[dst]:
                seen.add(dst)
                parent[dst] = (node, t)
                order.append(dst)
    return order, parent


def _why_not(space: TaskSpace, start: frozenset[str], before: tuple[str, ...], atom: str,
             alone: bool, complete: bool) -> str:
    here = "{" + ", ".join(a for a in space.atom_texts if a in start) + "}"
    cut = "" if complete else f" (the search stopped at its cap of {GOAL_STATES_CAP} markings)"
    if alone:
        return (f"goal atom {atom} cannot hold together with {', '.join(before)} in any marking reachable "
                f"from {here}{cut}")
    adders = [a.text for a in space.actions if atom in a.add]
    why = (f"the actions that make it hold ({', '.join(adders)}) are never enabled" if adders
           else "no action of the task space makes it hold")
    return f"goal atom {atom} holds in no marking reachable from {here}: {why}{cut}"
