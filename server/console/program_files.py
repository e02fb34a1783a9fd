"""Reading a program file for the console: parse, check, plan its durations and format its lines,
outside the session's lock and with progress (``server.console.work``).

``ProgramDesk.load`` calls ``read_program`` on the API's worker thread, then takes the session's
lock only to put what it read in place. A 20,000-line file takes seconds here (planning is most of
it); the session meanwhile answers jogs and clicks, and its link never waits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from server.console.program_entries import EntryViews
from server.console.statement_checks import checked_statement
from server.console.work import Work
from shared.cells.cell import Cell
from shared.errors import InputError, TeleprogError
from shared.language.parser import PROGRESS_EVERY, parse_json, parse_program
from shared.language.statements import is_task
from shared.motion.prefix_planner import PrefixPlanner
from shared.motion.task_effects import TaskObjects
from shared.program.editor import ProgramState

LOAD_PHASES = (("parse", 0.1), ("check", 0.06), ("plan", 0.6), ("format", 0.24))
"""A program file's load in steps, with their shares of a long load's time (20,000 lines)."""


@dataclass
class ReadProgram:
    """A file's program, checked, with its lines formatted and (from a known start) planned."""

    state: ProgramState
    entries: EntryViews
    planner: PrefixPlanner | None = None  # the durations' planner, when the start was known and it planned
    durations: list[float | None] | None = None  # as ``ProgramDesk.durations`` gives them


def read_program(text: str, name: str, cell: Cell, start_q: np.ndarray | None, work: Work,
                 objects: TaskObjects | None = None) -> ReadProgram:
    """The program of file ``name`` (text, or JSON for a .json name); a broken file or a broken
    rule is an ``InputError`` naming the file and where. ``start_q``: where the program starts
    (None: unknown, no durations); ``objects``: the movable objects and the grip there (default:
    the cell's as loaded)."""
    if name.lower().endswith(".json"):
        work.phase("parse", 1)
        parsed = parse_json(text, name)
    else:
        parse_step = work.phase("parse", max(1, text.count("\n")))
        parsed = parse_program(text, name, progress=lambda done, _total: parse_step(done))
    if not parsed.ok:
        lines = parsed.error_lines()
        more = f" (and {len(lines) - 1} more)" if len(lines) > 1 else ""
        raise InputError(lines[0] + more)
    state = ProgramState.of(parsed.statements)  # InputError when the rules are broken
    statements = state.statements
    check_step = work.phase("check", len(statements))
    for i, st in enumerate(statements):
        if i % PROGRESS_EVERY == 0:
            check_step(i)
        try:
            checked_statement(st)
        except TeleprogError as exc:
            raise InputError(f"{name}: statement {i + 1}: {exc}") from None
    read = ReadProgram(state, EntryViews())
    plan_step = work.phase("plan", len(statements))
    if statements and start_q is not None:
        planner = PrefixPlanner(cell.robot, cell, start_q, objects)
        try:
            plan = planner.plan(statements, progress=plan_step)
        except TeleprogError:
            pass  # no durations: ``ProgramDesk.durations`` says why when it plans
        else:
            read.planner, read.durations = planner, [None] * len(statements)
            for i, segment in enumerate(plan.segments):
                read.durations[i] = None if is_task(statements[i]) else float(segment.duration)
    format_step = work.phase("format", len(statements))
    for i, st in enumerate(statements):
        if i % PROGRESS_EVERY == 0:
            format_step(i)
        read.entries.text(st)
    return read
