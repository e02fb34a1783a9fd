"""The program's plan, kept: the durations the program view shows and the plan a submission
checks, from one ``PrefixPlanner`` that re-plans a changed program from its first changed
statement (a mixin of ``ProgramDesk``, which holds the editor and the program's start)."""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from server.console.context import ConsoleContext
from server.console.program_start import ProgramStart
from shared.errors import TeleprogError
from shared.motion.interpreter import Plan
from shared.motion.prefix_planner import PrefixPlanner
from shared.motion.task_effects import TaskObjects
from shared.program.editor import Editor
from shared.program.marks import task_indices

log = logging.getLogger(__name__)


def grip_key(objects: TaskObjects | None) -> bytes:
    """What of ``objects`` a plan's tasks depend on, as bytes for the planner cache's key."""
    if objects is None:
        return b""
    grip = objects.grip
    placed = b"".join(name.encode() + np.asarray(pose).tobytes() for name, pose in sorted(objects.poses.items()))
    return placed + (b"" if grip is None else grip.name.encode() + np.asarray(grip.tcp_T_object).tobytes())


class ProgramPlans:
    """The desk's plans (the desk holds ``_ctx``, ``_editor`` and ``start``)."""

    _ctx: ConsoleContext
    _editor: Editor
    start: ProgramStart

    def __init__(self) -> None:
        self.objects_at_start: Callable[[], TaskObjects] | None = None
        """The objects and the grip where the program starts (set by the session: the virtual cell's)."""
        self._durations: tuple[tuple, list[float | None]] | None = None  # (key, durations)
        self._planner: tuple[bytes, PrefixPlanner] | None = None  # (start joints and grip, its planner)

    def durations(self) -> list[float | None]:
        """Each real statement's planned duration (s) from the program's start; ``None`` where
        it is not known: a task (only the robot knows how long), a statement at or after a
        planning refusal, or every statement when the start is unknown. Planned once per change."""
        with self._ctx.lock:
            statements = tuple(self._editor.state.statements)
            start = self.start
            key = (statements, start.q.tobytes(), start.unknown)
            if self._durations is not None and self._durations[0] == key:
                return self._durations[1]
            durations: list[float | None] = [None] * len(statements)
            if statements and not start.unknown:
                planner = self.prefix_planner(start.q)
                try:
                    planner.plan(statements)
                except TeleprogError as exc:
                    self._planner = None
                    log.info("no durations: the program cannot be planned (%s)", exc)
                else:  # kept per statement by the planner; only the robot knows how long a task takes
                    durations = (planner.durations() + durations)[:len(statements)]
                    for i in task_indices(self._editor.state.marks):
                        durations[i] = None
            self._durations = (key, durations)
            return durations

    def planned(self, stop: int) -> Plan:
        """The plan of statements ``0..stop-1`` from the program's (known) start, from the prefix
        planner that keeps the program's plan (under the lock): what is planned already is not
        planned again. Raises ``InputError`` as ``plan_or_refuse`` does."""
        return self.prefix_planner(self.start.q).plan(self._editor.state.statements[:stop])

    def prefix_planner(self, q_start: np.ndarray) -> PrefixPlanner:
        """The planner of durations from ``q_start``: it re-plans a changed program only from its
        first changed statement (a generated statement added while driving: one statement)."""
        objects = self.objects_at_start() if self.objects_at_start is not None else None
        key = q_start.tobytes() + grip_key(objects)
        if self._planner is None or self._planner[0] != key:
            self._planner = (key, PrefixPlanner(self._ctx.robot, self._ctx.cell, q_start, objects))
        return self._planner[1]
