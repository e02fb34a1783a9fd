"""Recognise the actions of a program by playing it on the virtual cell (``teleprog net
recognise``): the console's own interpreter and planner give the arm's motion, the object world
does what the task calls do to the objects (a grasp holds, an insertion seats), and the task
coordinator recognises the actions from the faces' contacts at every sample.

The statement names of the task calls play no part in the recognition: ``TASK grasp(peg)``
closes the gripper in the object world and the fingers' contacts decide whether the hand now
holds the peg; a peg lifted out of a hole by plain DRAW motions is ``part`` as surely as one the
robot's ``extract_peg`` lifts.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from shared.cells.object_world import ObjectWorld
from shared.language.statements import Statement, TaskCall
from shared.motion import plan_program
from shared.motion.interpreter import Plan
from shared.motion.prefix_planner import PrefixPlanner
from shared.motion.frames import CellFrames
from shared.motion.segment import SegmentKind
from shared.tasknet.contacts import CellState, ContactModel
from shared.tasknet.coordinator import RecognisedAction, TaskCoordinator, TaskNet, generate_task_net
from shared.tasknet.taskspace import TaskSpace

SAMPLE_DT_S = 0.01
"""The time step (s) at which a planned motion is sampled for recognition."""
TASK_STEPS = 25
"""Samples along a task call that moves the arm (``extract_peg``'s lift, ``insert_peg``'s descent
to the seat its effect names)."""


@dataclass(frozen=True)
class ProgramRecognition:
    actions: tuple[RecognisedAction, ...]
    m0: tuple[str, ...]
    final_marking: tuple[str, ...]
    net: TaskNet
    samples: int
    refusal: str | None = None  # the planner's refusal, when the program could not be played whole
    starts: tuple[float, ...] = ()
    """Each planned statement's start time (s) on the play's clock, the clock of ``actions[i].t``."""


def play(plan: Plan, cell, world: ObjectWorld, dt: float = SAMPLE_DT_S) -> Iterator[tuple[np.ndarray, float, int]]:
    """The arm along ``plan`` on ``cell``, every ``dt`` s of the plan's clock and at each
    statement's end: ``(q, t, statement number)``. A task call that moves the arm is sampled in
    ``TASK_STEPS`` steps; its effect on ``world`` (a grasp holds, an insertion seats) is applied
    just before its last sample, so ``world`` read at each sample is the cell at that moment."""
    frames = CellFrames.from_cell(cell)
    for k in range(len(plan.segments)):
        yield from play_segment(plan, k, cell, frames, world, dt)


def play_segment(plan: Plan, k: int, cell, frames: CellFrames, world: ObjectWorld,
                 dt: float = SAMPLE_DT_S) -> Iterator[tuple[np.ndarray, float, int]]:
    """:func:`play` of the plan's segment ``k`` alone (``world``: the cell before it)."""
    seg, t0 = plan.segments[k], plan.start_times[k]
    number = seg.index + 1
    if seg.kind is SegmentKind.TASK:
        if not np.allclose(seg.q_start, seg.q_end):
            for s in np.linspace(0.0, 1.0, TASK_STEPS):
                yield seg.q_start + s * (seg.q_end - seg.q_start), float(t0), number
        st = seg.statement
        assert isinstance(st, TaskCall)
        world.apply_task(st.name, tuple(st.args), frames.world_T_tcp(cell.robot, seg.q_end))
        yield seg.q_end, float(t0), number
        return
    if seg.duration <= 0.0:
        return
    ts = np.append(np.arange(t0, t0 + seg.duration, dt), t0 + seg.duration)
    qs = plan.sample(ts).q
    qs[-1] = seg.q_end  # the plan's clock gives the end instant to the tasks after it (no time of their own)
    for t, q in zip(ts, qs):
        yield q, float(t), number


def recognise_program(program: Sequence[Statement], cell, space: TaskSpace, start_q: np.ndarray | None = None,
                      world: ObjectWorld | None = None,
                      progress: Callable[[int, int], None] | None = None) -> ProgramRecognition:
    """Play ``program`` on ``cell`` from ``start_q`` (the cell's home pose) with the objects of
    ``world`` (changed in place; the cell as loaded when None) and recognise it.
    ``progress(statements played, statements)`` is called as the play enters each statement."""
    robot = cell.robot
    plan = plan_program(program, robot, cell, start_q)
    frames = CellFrames.from_cell(cell)
    world = ObjectWorld(cell) if world is None else world
    contacts = ContactModel(space, cell)
    coordinator = TaskCoordinator(space, contacts, CellState.of_world(world, frames.world_T_tcp(robot, plan.q_start)))
    samples = 0
    current = None
    for q, t, number in play(plan, cell, world):
        samples += 1
        if progress is not None and number != current:
            current = number
            progress(max(0, (number or 1) - 1), len(program))
        coordinator.observe(CellState.of_world(world, frames.world_T_tcp(robot, q)), t, number)
    return _recognition(space, coordinator, plan, samples)


def _recognition(space: TaskSpace, coordinator: TaskCoordinator, plan: Plan, samples: int) -> ProgramRecognition:
    actions = tuple(coordinator.actions)
    net = generate_task_net(space, coordinator.m0, [a.action for a in actions])
    return ProgramRecognition(
        actions, tuple(coordinator.ordered(coordinator.m0)), tuple(coordinator.ordered(coordinator.marking)), net,
        samples, None if plan.refusal is None else str(plan.refusal), tuple(float(t) for t in plan.start_times),
    )


@dataclass(frozen=True)
class _After:
    """The play's state after one statement: the objects, the marking, how many actions and samples."""

    world: ObjectWorld
    marking: frozenset[str]
    actions: int
    samples: int
    truth: dict[str, bool]


class PrefixRecognition:
    """:func:`recognise_program` for successive versions of a program from one start, playing
    each version from its first statement that changed (as ``PrefixPlanner`` plans it).

    Recognition is sequential: what a statement's samples recognise depends only on the objects,
    the marking and the clock before it. So the play keeps that state after every statement and a
    new version restores it at the first statement that differs: a statement added at the end is
    played alone, and a preview of a range whose prefix was played is not played again. The
    result is :func:`recognise_program`'s (``tests/tasknet/test_prefix_recognition.py``)."""

    def __init__(self, cell, space: TaskSpace, start_q: np.ndarray, world: ObjectWorld | None = None) -> None:
        """``world``: the objects at the start (copied; default: the cell as loaded)."""
        self._cell, self._space = cell, space
        self._frames = CellFrames.from_cell(cell)
        self._planner = PrefixPlanner(cell.robot, cell, np.asarray(start_q, dtype=float))
        self._world = (ObjectWorld(cell) if world is None else world).copy()
        q0 = np.asarray(start_q, dtype=float)
        self._coordinator = TaskCoordinator(space, ContactModel(space, cell),
                                            CellState.of_world(self._world, self._frames.world_T_tcp(cell.robot, q0)))
        self._played: list[Statement] = []  # the statements played, one state kept after each
        self._after: list[_After] = [self._snapshot(0)]
        self.replayed = 0
        """Statements played by the last :meth:`recognise` (the rest was kept)."""
        self.q_end = np.asarray(start_q, dtype=float).copy()
        """Where the last :meth:`recognise` left the arm (the plan's end, or the start of its refusal)."""

    def _snapshot(self, samples: int) -> _After:
        c = self._coordinator
        return _After(self._world.copy(), c.marking, len(c.actions), samples, dict(c._last_truth))  # noqa: SLF001

    def _restore(self, after: _After) -> None:
        c = self._coordinator
        self._world = after.world.copy()
        c.marking = after.marking
        del c.actions[after.actions:]
        c._last_truth = dict(after.truth)  # noqa: SLF001 - the coordinator's state, put back as it was

    def recognise(self, program: Sequence[Statement],
                  progress: Callable[[int, int], None] | None = None) -> ProgramRecognition:
        """The recognition of ``program`` from this start; ``progress`` as :func:`recognise_program`'s."""
        program = list(program)
        plan = self._planner.plan(program)
        segments = plan.segments
        keep = 0
        for old, new in zip(self._played, segments):
            if old is not new.statement and old != new.statement:
                break
            keep += 1
        keep = min(keep, len(self._after) - 1)
        del self._played[keep:]
        del self._after[keep + 1:]
        self._restore(self._after[keep])
        samples = self._after[keep].samples
        robot = self._cell.robot
        for k in range(keep, len(segments)):
            if progress is not None:
                progress(k, len(program))
            for q, t, number in play_segment(plan, k, self._cell, self._frames, self._world):
                samples += 1
                self._coordinator.observe(CellState.of_world(self._world, self._frames.world_T_tcp(robot, q)), t, number)
            self._played.append(segments[k].statement)
            self._after.append(self._snapshot(samples))
        self.replayed = len(segments) - keep
        self.q_end = plan.q_final.copy()
        return _recognition(self._space, self._coordinator, plan, samples)

    def world_at_end(self) -> ObjectWorld:
        """The objects where the last :meth:`recognise` left them (a copy); the arm at ``q_end``."""
        return self._world.copy()
