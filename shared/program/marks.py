"""Each statement's kind as a few bits, kept beside the program and spliced on every edit.

The rules a whole program must keep (``shared.language.task_rule``: nothing that moves the arm
after a task whose end only the robot knows; ``shared.program.free_rules``: the gripper state
task calls need) read only a few facts of each statement. Scanning 10,000 statements for them in
Python on every edit costs milliseconds and grows with the program; an edit changes one statement
or a range. So a program state keeps these facts as one small array, an edit computes them for
the statements it puts in and splices the array (numpy, a copy of bytes), and the rules read the
array: the first task whose end is unknown is one ``argmax``, whether anything moves after it
one ``any``, the task calls one ``flatnonzero``. The Python work of an edit is proportional to
what it changes; what stays proportional to the program is a copy of a byte per statement.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from shared.language.statements import is_task
from shared.language.task_rule import TaskRuleBreak, UnknownPose, moves_arm, task_arm_end, why_not
from shared.program.rules import is_real

MOVES = np.uint8(1)
"""An action, or a task call not known to keep the arm still (``task_rule.moves_arm``)."""
UNKNOWN_END = np.uint8(2)
"""A task call after which the arm's pose is unknown until the robot reports it."""
TASK = np.uint8(4)
"""A task call (the gripper's rules read only these)."""
NOT_REAL = np.uint8(8)
"""Not an action, a parameter statement or a task call: no program may hold it."""

EMPTY = np.zeros(0, dtype=np.uint8)


def mark(statement: object) -> int:
    """The bits of one statement."""
    if not is_real(statement):
        return int(NOT_REAL)
    bits = int(MOVES) if moves_arm(statement) else 0
    if is_task(statement):
        bits |= int(TASK)
        if task_arm_end(statement.name) == "unknown":
            bits |= int(UNKNOWN_END)
    return bits


def marks_of(statements: Sequence[object]) -> np.ndarray:
    """The bits of every statement (a whole program read at once)."""
    if not statements:
        return EMPTY
    return np.fromiter((mark(s) for s in statements), dtype=np.uint8, count=len(statements))


def splice(marks: np.ndarray, first: int, stop: int, inserted: np.ndarray) -> np.ndarray:
    """``marks`` with ``marks[first:stop]`` replaced by ``inserted`` (an insertion, a deletion, a
    replacement, a submission's cut)."""
    return np.concatenate((marks[:first], inserted, marks[stop:]))


def moved(marks: np.ndarray, first: int, stop: int, by: int) -> np.ndarray:
    """``marks`` with entries ``first..stop`` (both included) moved ``by`` places."""
    block = marks[first:stop + 1]
    rest = np.concatenate((marks[:first], marks[stop + 1:]))
    at = first + by
    return np.concatenate((rest[:at], block, rest[at:]))


def first_not_real(marks: np.ndarray) -> int | None:
    """The index of the first entry no program may hold, or None."""
    bad = np.flatnonzero(marks & NOT_REAL)
    return int(bad[0]) if bad.size else None


def unknown_pose(statements: Sequence[object], marks: np.ndarray) -> UnknownPose | None:
    """The first task call after which the arm's pose is unknown (it stays unknown), or None."""
    hits = np.flatnonzero(marks & UNKNOWN_END)
    if not hits.size:
        return None
    index = int(hits[0])
    return UnknownPose(statements[index].name, index)


def first_break(statements: Sequence[object], marks: np.ndarray) -> TaskRuleBreak | None:
    """The first statement that may not stand where it is (``task_rule.task_rule_breaks``'s
    first): the first that moves the arm after the first task whose end is unknown."""
    unknown = unknown_pose(statements, marks)
    if unknown is None:
        return None
    after = np.flatnonzero(marks[unknown.index + 1:] & MOVES)
    if not after.size:
        return None
    index = unknown.index + 1 + int(after[0])
    return TaskRuleBreak(index, unknown, f"statement {index + 1}: " + why_not(statements[index], unknown))


def task_indices(marks: np.ndarray) -> list[int]:
    """Where the task calls are, in order."""
    return np.flatnonzero(marks & TASK).tolist()
