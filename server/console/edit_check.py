"""Free editing's last check: the statements after an edit, re-planned against the robot and the cell.

The editor (``shared.program.free_rules``) lets any statement or range be deleted, replaced, moved
or inserted, and refuses what it can judge alone (the task rule, the gripper state of later task
calls). What it cannot judge is the path: after a motion in the middle is deleted, the next one
starts somewhere else, and its straight line from there may now leave a joint range, need an
unreachable pose or run the arm into the cell. Here the program after the edit is planned from its
start and the statements after the edit point are checked as the preview checks them
(``Previewer.path_not_clear``: the planner's refusal, joint limits, collisions of the arm).

Only what the edit breaks is refused: a statement that was there before the edit, ran before it
and cannot run after it. A statement the edit itself put in (an insertion, a replacement) is not
refused for its own path, as in the thesis's editor: its preview shows where it fails. Nothing is
planned when no statement follows the edit (the operator driving and generating at the end pays
nothing), nor when the program's start is unknown (after a task only the robot can finish).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable, Mapping

from shared.errors import TeleprogError
from shared.language.formatter import format_statement
from shared.program.editor import Editor
from shared.program.rules import Refusal, Rule

log = logging.getLogger(__name__)

_WHERE = re.compile(r"^statement \d+: ")
_WHEN = re.compile(r" at t=[-\d.]+ s")  # a time from the checked range's start: no use to the operator
_REASON_ID = re.compile(r" \([a-z_]+\)$")  # the planner's reason id at the end of its sentence


def plain(message: str) -> str:
    """A check's sentence without the statement number it starts with (numbered in the edited
    program, not the one the operator sees), the time within the checked range, or the planner's
    reason id it ends with: ``link6 touches peg``, ``joint 5 leaves its range``."""
    return _REASON_ID.sub("", _WHEN.sub("", _WHERE.sub("", message)))


PathCheck = Callable[[Editor, int, int], Mapping[int, str]]
"""``check(editor, start, stop)``: for each statement of ``editor``'s program in ``start..stop-1``
whose planned path is not clear, why (the previewer's check of that program)."""


def rest_breaks(path_not_clear: PathCheck, before: Editor, trial: Editor) -> Refusal | None:
    """Why the edit that turned ``before`` into ``trial`` breaks a statement after it, or None
    (under the session's lock)."""
    old, new = before.state.statements, trial.state.statements
    first = next((i for i, (a, b) in enumerate(zip(old, new)) if a is not b), min(len(old), len(new)))
    old_index = {id(s): i for i, s in enumerate(old)}
    rest = [i for i in range(first, len(new)) if id(new[i]) in old_index]
    if not rest:
        return None  # nothing that was there before comes after the edit
    try:
        broken_before = {id(old[i]) for i in path_not_clear(before, first, len(old))}
        broken_after = path_not_clear(trial, first, len(new))
    except TeleprogError as exc:  # the planner failed on numbers it was given: the preview will say so
        log.info("the edit's rest was not checked: %s", exc)
        return None
    for index in rest:
        statement = new[index]
        if index in broken_after and id(statement) not in broken_before:
            line = old_index[id(statement)]
            return Refusal(
                Rule.EDIT_PATH,
                f"statement {line + 1} ({format_statement(statement)}) could no longer run after this edit: "
                f"{plain(broken_after[index])}",
                line,
            )
    return None
