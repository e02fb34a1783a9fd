"""Task coordination (§3.5.3-3.5.5): the marking of the task space's net follows a cell's states,
the actions that moved it are recognised, and the performed task becomes a condition/event net.

:class:`TaskCoordinator` holds a marking ``M`` (the set of true atoms), starting from ``M0``
recognised in the cell as loaded. Each :meth:`~TaskCoordinator.observe` of a cell state asks the
contact model only for the atoms the enabled transitions would change (§3.5.3) and fires the
enabled transition whose effects all hold: its added atoms true and its deleted atoms false.
Firing only enabled transitions keeps Definition 3.27's recognition conditions by construction:
the new marking is reachable from ``M0`` and from the marking the action started in. A state no
enabled transition explains is left to the operator, as the thesis does (§3.5.4): the marking
stays and :meth:`~TaskCoordinator.unexplained` says which checked atoms disagree with it.

:func:`generate_task_net` is §3.5.5: the distinct actions of the sequence become the events,
the atoms they touch the conditions (numbered in order of first use along the sequence, the
preconditions of an action before its results, which gives Table 3.2's numbering), and the
conditions true in ``M0`` the initial case.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from shared.tasknet.cenet import ConditionEventModel, ConditionModel, EventModel, condition_event_net
from shared.tasknet.contacts import CellState, ContactModel
from shared.tasknet.ptnet import PTNet
from shared.tasknet.taskspace import GroundAction, TaskSpace

MAX_FIRINGS_PER_STATE = 8
"""How many actions one observed state may complete (a coarse step can finish two: a release
that also ends a mate is still two actions)."""
MAX_FOLLOW_ACTIONS = 8
"""How many actions :meth:`TaskCoordinator.follow` may find between a marking and a cell that
jumped (a whole submitted transfer is four)."""


@dataclass(frozen=True)
class RecognisedAction:
    """An action recognised at one observation: its text (``part(PEG,HOLE1)``), its place in
    the sequence, the time and the statement (1-based program number) it happened in."""

    action: str
    index: int
    t: float | None = None
    statement: int | None = None
    marking: tuple[str, ...] = ()  # the marking after it


class TaskCoordinator:
    """The marking of one side's cell (the virtual arm's or the robot's) and what it recognised."""

    def __init__(self, space: TaskSpace, contacts: ContactModel, initial: CellState) -> None:
        self.space = space
        self.contacts = contacts
        truth = contacts.evaluate(initial)
        self.m0: frozenset[str] = frozenset(a for a, v in truth.items() if v)
        self.marking: frozenset[str] = self.m0
        self.actions: list[RecognisedAction] = []
        self._last_truth: dict[str, bool] = truth
        # per marking: the enabled actions, each with its added atoms, and the atoms they change
        # (observe runs on every state the arm passes through; the marking rarely changes)
        self._at_marking: dict[frozenset[str], tuple[tuple[tuple[GroundAction, tuple[str, ...]], ...], tuple[str, ...]]] = {}

    # -- the net at the current marking ----------------------------------------------------------
    def enabled(self, marking: frozenset[str] | None = None) -> list[GroundAction]:
        """Actions whose preconditions hold and whose results are not already all holding
        (a C/E net's event is enabled when its pre-conditions hold and its post-conditions,
        apart from side conditions, do not), at ``marking`` (default: the current one)."""
        m = self.marking if marking is None else marking
        out = []
        for act in self.space.actions:
            if not all(a in m for a in act.pre):
                continue
            if any(a in m for a in self._added(act)):
                continue
            out.append(act)
        return out

    @staticmethod
    def _added(act: GroundAction) -> tuple[str, ...]:
        """The atoms ``act`` makes hold that did not have to hold before it."""
        return tuple(a for a in act.post if a not in act.pre)

    @classmethod
    def _changes(cls, act: GroundAction) -> tuple[str, ...]:
        return tuple(dict.fromkeys([*cls._added(act), *act.delete]))

    def observe(self, state: CellState, t: float | None = None, statement: int | None = None) -> list[RecognisedAction]:
        """Recognise the actions ``state`` completes; returns them (usually none)."""
        done: list[RecognisedAction] = []
        for _ in range(MAX_FIRINGS_PER_STATE):
            enabled, wanted = self._options()
            if not wanted:
                break
            truth = self.contacts.evaluate(state, wanted)
            self._last_truth.update(truth)
            fired = None
            for act, added in enabled:
                if all(truth[a] for a in added) and not any(truth[a] for a in act.delete):
                    fired = act
                    break
            if fired is None:
                break
            self.marking = frozenset((self.marking - set(fired.delete)) | set(fired.post))
            rec = RecognisedAction(fired.text, len(self.actions), t, statement, tuple(self.ordered(self.marking)))
            self.actions.append(rec)
            done.append(rec)
        return done

    def _options(self) -> tuple[tuple[tuple[GroundAction, tuple[str, ...]], ...], tuple[str, ...]]:
        """At the current marking: the enabled actions with their added atoms, and the atoms
        they change (what :meth:`observe` asks the contact model for)."""
        kept = self._at_marking.get(self.marking)
        if kept is None:
            enabled = tuple((act, self._added(act)) for act in self.enabled())
            wanted = tuple(dict.fromkeys(a for act, _ in enabled for a in self._changes(act)))
            kept = self._at_marking[self.marking] = (enabled, wanted)
        return kept

    def follow(self, state: CellState, t: float | None = None, statement: int | None = None) -> list[RecognisedAction] | None:
        """The cell jumped to ``state`` (a submitted range, a report moved it at once): fire the
        shortest sequence of enabled actions (at most ``MAX_FOLLOW_ACTIONS``; the task space's
        order breaks ties) after which the marking agrees with every atom ``state`` shows. The
        actions fired, ``[]`` when the marking agrees already, None (nothing changed) when no such
        sequence exists: the state is left to the operator (:meth:`unexplained`)."""
        truth = self.contacts.evaluate(state)
        self._last_truth.update(truth)
        goal = frozenset(a for a, v in truth.items() if v)
        path = self.path_to(goal)
        return None if path is None else self._fire(path, t, statement)

    def path_to(self, goal: frozenset[str], start: frozenset[str] | None = None) -> list[GroundAction] | None:
        """The shortest run of enabled actions (at most ``MAX_FOLLOW_ACTIONS``; the task space's
        order breaks ties) from ``start`` (default: the marking) to the marking ``goal``: ``[]``
        when they are the same, None when no such run exists."""
        here = self.marking if start is None else start
        if here == goal:
            return []
        frontier: list[tuple[frozenset[str], tuple[GroundAction, ...]]] = [(here, ())]
        seen = {here}
        for _ in range(MAX_FOLLOW_ACTIONS):
            nxt = []
            for marking, path in frontier:
                for act in self.enabled(marking):
                    after = frozenset((marking - set(act.delete)) | set(act.post))
                    if after in seen:
                        continue
                    if after == goal:
                        return [*path, act]
                    seen.add(after)
                    nxt.append((after, (*path, act)))
            frontier = nxt
            if not frontier:
                break
        return None

    def _fire(self, acts: Sequence[GroundAction], t: float | None, statement: int | None) -> list[RecognisedAction]:
        done = []
        for act in acts:
            self.marking = frozenset((self.marking - set(act.delete)) | set(act.post))
            rec = RecognisedAction(act.text, len(self.actions), t, statement, tuple(self.ordered(self.marking)))
            self.actions.append(rec)
            done.append(rec)
        return done

    def take(self, state: CellState) -> bool:
        """The marking becomes what ``state`` shows, with no action recognised (a re-sync: the
        cell is taken from the other side as it is). True when the marking changed."""
        truth = self.contacts.evaluate(state)
        self._last_truth.update(truth)
        marking = frozenset(a for a, v in truth.items() if v)
        changed = marking != self.marking
        self.marking = marking
        return changed

    def unexplained(self, state: CellState) -> dict[str, bool]:
        """Every atom whose truth in ``state`` disagrees with the marking: ``{atom: observed}``."""
        truth = self.contacts.evaluate(state)
        self._last_truth.update(truth)
        return {a: v for a, v in truth.items() if v != (a in self.marking)}

    def ordered(self, atoms: frozenset[str] | set[str]) -> list[str]:
        """Atoms in the task space's order."""
        return [a for a in self.space.atom_texts if a in atoms]

    def reset(self, state: CellState) -> None:
        """Start again from ``state`` (a program reloaded, a re-sync): a new ``M0``, no actions."""
        truth = self.contacts.evaluate(state)
        self.m0 = self.marking = frozenset(a for a, v in truth.items() if v)
        self.actions = []
        self._last_truth = truth


@dataclass(frozen=True)
class TaskNet:
    """The generated task model: the compact C/E form (places ``P1..``, transitions ``T1..``) and
    the same net as a P/T net for firing and analysis."""

    model: ConditionEventModel
    net: PTNet

    def place_of(self, atom: str) -> str:
        return next(p.id for p in self.model.places if p.predicate == atom)

    def transition_of(self, action: str) -> str:
        return next(t.id for t in self.model.transitions if t.action == action)


def generate_task_net(space: TaskSpace, m0: frozenset[str], actions: Sequence[str], net_id: str = "task") -> TaskNet:
    """§3.5.5: the C/E net of the performed task from the action sequence and ``M0``.

    Events are the distinct actions, numbered in the order of the task space's rules (then of
    first use); conditions are the atoms those actions need or produce, numbered in the order
    the sequence first uses them. Definition 3.29's reduction merges elements with equal pre-
    and post-sets; the elements here are distinct atoms and actions, and two distinct conditions
    that happen to be structurally alike (HANDEEMPTY and PEGFREE(PEG) once release frees the peg)
    stay apart: each is a predicate a report can contradict, and Table 3.2 keeps them apart too.
    """
    distinct = [space.action(a) for a in dict.fromkeys(actions)]
    # no action yet: the task is the conditions that hold, with no event
    atoms: list[str] = [] if distinct else [a for a in space.atom_texts if a in m0]
    for act in distinct:
        for a in (*act.pre, *act.post):
            if a not in atoms:
                atoms.append(a)
    place_id = {a: f"P{i + 1}" for i, a in enumerate(atoms)}
    by_rule = sorted(distinct, key=lambda act: (space.rule_order(act), distinct.index(act)))
    events = [
        EventModel(id=f"T{i + 1}", action=act.text, pre=[place_id[a] for a in act.pre], post=[place_id[a] for a in act.post])
        for i, act in enumerate(by_rule)
    ]
    conditions = {place_id[a]: a for a in atoms}
    initial = [place_id[a] for a in atoms if a in m0]
    net = condition_event_net(conditions, events, initial, net_id)
    model = ConditionEventModel(
        places=[ConditionModel(id=place_id[a], predicate=a) for a in atoms],
        transitions=events,
        initial_marking=initial,
    )
    return TaskNet(model, net)
