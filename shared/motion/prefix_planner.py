"""Planning a program that changes near its end, from its first changed statement on.

The console shows every statement's planned duration and plans again whenever the program
changes. While the operator drives, the program changes at its end: a generated statement is
added, or the last one replaced as its stroke goes on. Planning is sequential - a statement's
segment depends only on the interpreter's state before it (joints, speed, mode, what a task left
unknown) - so keeping that state for every statement of the last plan lets the next version be
planned from the first statement that differs, with the result ``plan_program`` gives from the
start (``tests/motion/test_prefix_planner.py``). Appending to an n-statement program costs one
statement's planning instead of n.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from shared.cells.cell import Cell
from shared.errors import InputError, TeleprogError
from shared.language.parser import PROGRESS_EVERY
from shared.language.statements import Statement
from shared.motion.frames import CellFrames
from shared.motion.interpreter import Interpreter, InterpreterState, Plan
from shared.motion.plan_check import PLANNER_FAILURES, planner_failure
from shared.motion.refusal import PlanRefused
from shared.motion.segment import Segment
from shared.motion.task_effects import TaskObjects
from shared.robots.model import Robot


def common_prefix(a: Sequence, b: Sequence) -> int:
    """How many leading items ``a`` and ``b`` share (equal, or the same object). Slices are
    compared in C (``==`` tries identity first), halving the range: a program of 10,000
    statements that changed at its end costs 14 slice comparisons, not 10,000 Python steps."""
    n = min(len(a), len(b))
    if a[:n] == b[:n]:
        return n
    lo, hi = 0, n  # a[:lo] == b[:lo]; a[:hi] != b[:hi]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if a[:mid] == b[:mid]:
            lo = mid
        else:
            hi = mid
    return lo


class PrefixPlanner:
    """``plan_program(statements, robot, cell, start_q)`` for successive versions of a program,
    re-planning only from the first statement that changed since the last call."""

    def __init__(self, robot: Robot, cell: Cell, start_q: Sequence[float] | np.ndarray,
                 objects: TaskObjects | None = None) -> None:
        """``objects``: the movable objects and the grip at the start (default: the cell's as loaded)."""
        if cell.robot.name != robot.name:
            raise InputError(f"cell {cell.name!r} holds robot {cell.robot.name!r}, not {robot.name!r}")
        self._interp = Interpreter(robot, start_q, CellFrames.from_cell(cell), None, cell.features, None,
                                   TaskObjects.of_cell(cell) if objects is None else objects)
        self._statements: list[Statement] = []  # the last version planned
        self._segments: list[Segment] = []  # its segments up to its first refusal
        self._durations: list[float] = []  # each segment's duration, kept as the segments are
        self._states: list[InterpreterState] = [self._interp.state]  # the state before each segment, and after the last

    def plan(self, statements: Sequence[Statement], progress: Callable[[int], None] | None = None) -> Plan:
        """Every statement planned in order, stopping at the first refusal, as ``plan_program``.
        A numerical failure of the planner (an overflow, a NaN reaching an index) is refused as
        ``InputError`` naming it, as ``plan_or_refuse`` does. ``progress(statements planned)``
        is called every ``PROGRESS_EVERY`` statements planned anew."""
        statements = list(statements)
        keep = min(common_prefix(self._statements, statements), len(self._segments))
        del self._segments[keep:]
        del self._durations[keep:]
        del self._states[keep + 1:]
        self._statements = statements[:keep]
        self._interp.restore(self._states[keep])
        refusal: PlanRefused | None = None
        for k, statement in enumerate(statements[keep:], start=keep):
            if progress is not None and k % PROGRESS_EVERY == 0 and k > keep:
                progress(k)
            try:
                with np.errstate(all="ignore"):
                    segment = self._interp.plan_next(statement)
            except PlanRefused as exc:
                refusal = exc
                break
            except TeleprogError:
                raise
            except PLANNER_FAILURES as exc:
                raise planner_failure(exc, f"statement {len(self._segments) + 1}") from None
            self._segments.append(segment)
            self._durations.append(float(segment.duration))
            self._states.append(self._interp.state)
            self._statements.append(statement)
        return Plan.of(self._segments, self._states[0].q.copy(), self._states[-1], refusal, self._durations)

    def durations(self) -> list[float]:
        """Each segment's duration (s) in the last plan, up to its first refusal (a copy)."""
        return list(self._durations)

    def plan_first(self, statements: Sequence[Statement], stop: int) -> Plan:
        """The plan of ``statements[:stop]`` (as ``plan_program`` gives it), taken from the plan
        of all of ``statements``, which stays kept: a preview of a range and the program's
        durations share one planning, and neither re-plans what the other planned."""
        try:
            refusal = self.plan(statements).refusal
        except TeleprogError:  # a numerical failure past ``stop`` is not this prefix's business
            if len(self._segments) < stop:
                raise
            refusal = None
        n = min(stop, len(self._segments))
        refusal = refusal if stop > n else None  # planning stopped before ``stop``
        return Plan.of(self._segments[:n], self._states[0].q.copy(), self._states[n], refusal)
