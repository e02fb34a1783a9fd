"""Run a program against a sensor model: plan a statement, play it, go on from where it stopped.

This is the loop the preview runs (and the shape of the telerobot's executor loop): each
statement is planned from where the previous one really ended, so a motion cut short by its
UNTIL condition is followed from the stop, not from its planned end. Task calls are not run
here (the telerobot's task layer runs them); the simulation takes the task's contract from the
planner (still, retract) and, after a task whose end is unknown, plans only what may follow it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from shared.language.statements import Statement
from shared.motion.interpreter import Interpreter
from shared.motion.refusal import PlanRefused
from shared.motion.segment import Outcome, Segment, SegmentKind
from shared.motion.sensors import SensorModel


@dataclass(frozen=True)
class StatementRun:
    """One statement as it ran: its segment, what happened (None for a task, which the
    executor runs), and when it started on the program's clock (s)."""

    segment: Segment
    outcome: Outcome | None
    t_start: float

    @property
    def t_end(self) -> float:
        return self.t_start + (self.outcome.t_stop if self.outcome is not None else 0.0)


@dataclass(frozen=True)
class ProgramRun:
    runs: tuple[StatementRun, ...]
    q_final: np.ndarray
    refusal: PlanRefused | None = None

    @property
    def duration(self) -> float:
        return self.runs[-1].t_end if self.runs else 0.0


def simulate_program(
    program: Sequence[Statement],
    interpreter: Interpreter,
    sensors: SensorModel | None = None,
    dt: float = 0.01,
    t0: float = 0.0,
) -> ProgramRun:
    """Plan and play ``program`` from the interpreter's state at period ``dt``; stops at the
    first refusal. The interpreter is left where the run ended."""
    runs: list[StatementRun] = []
    t = t0
    refusal: PlanRefused | None = None
    for statement in program:
        try:
            segment = interpreter.plan_next(statement)
        except PlanRefused as exc:
            refusal = exc
            break
        if segment.kind is SegmentKind.TASK:
            runs.append(StatementRun(segment, None, t))
            continue
        outcome = segment.run(sensors, dt, t)
        if outcome.stopped_early:
            interpreter.resume_at(outcome.q_stop)
        runs.append(StatementRun(segment, outcome, t))
        t += outcome.t_stop
    return ProgramRun(tuple(runs), interpreter.state.q.copy(), refusal)
