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
    robot = cell.robot
    frames = CellFrames.from_cell(cell)
    for seg, t0 in zip(plan.segments, plan.start_times):
        number = seg.index + 1
        if seg.kind is SegmentKind.TASK:
            if not np.allclose(seg.q_start, seg.q_end):
                for s in np.linspace(0.0, 1.0, TASK_STEPS):
                    yield seg.q_start + s * (seg.q_end - seg.q_start), float(t0), number
            st = seg.statement
            assert isinstance(st, TaskCall)
            world.apply_task(st.name, tuple(st.args), frames.world_T_tcp(robot, seg.q_end))
            yield seg.q_end, float(t0), number
            continue
        if seg.duration <= 0.0:
            continue
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
    actions = tuple(coordinator.actions)
    net = generate_task_net(space, coordinator.m0, [a.action for a in actions])
    return ProgramRecognition(
        actions, tuple(coordinator.ordered(coordinator.m0)), tuple(coordinator.ordered(coordinator.marking)), net,
        samples, None if plan.refusal is None else str(plan.refusal), tuple(float(t) for t in plan.start_times),
    )
