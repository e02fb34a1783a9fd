"""The editing rules of thesis §4.3.6, literally: the editor's *strict* mode.

Each function answers "why may this edit not be made under the thesis's rules?" for a
:class:`~shared.program.editor.ProgramState` (``None``: it may), after the checks both modes
share (the preview lock, a selection inside the program, the trailing empty statement). The rules
themselves are listed in ``shared.program.rules``; in short, continuity is kept by letting only
the last motion change: an action is inserted only before the trailing empty statement, deleted
or given new parameters only when it stands just before it, and a task call only goes at the end.

"Just before the trailing empty statement" is read literally, as in the thesis: no statement at
all (not even a SPEED) may stand between the action and the empty statement. A range delete
generalises the single rule: the range may hold motions only when nothing but the empty statement
follows it; a range of parameter statements (and tasks that keep the arm still) may go anywhere.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from shared.language.statements import Statement, is_action, is_task
from shared.language.task_rule import may_follow, moves_arm, why_not
from shared.program.rules import Refusal, Rule, action_body, describe, is_real

if TYPE_CHECKING:
    from shared.program.editor import ProgramState


def strict_insert(state: ProgramState, statement: Statement) -> Refusal | None:
    """Actions and task calls only before the trailing empty statement; nothing that moves the
    arm after a task whose end pose is unknown."""
    at_end = state.selected_index == state.empty_index
    if is_action(statement) and not at_end:
        return Refusal(
            Rule.INSERT_ACTION_AT_END,
            f"a {statement.kind} action can only be inserted before the trailing empty statement "
            f"(statement {state.selected_index + 1} is selected); inserting it here would break action continuity",
            state.selected_index,
        )
    if is_task(statement) and not at_end:
        return Refusal(
            Rule.INSERT_TASK_AT_END,
            f"a task call can only be inserted before the trailing empty statement "
            f"(statement {state.selected_index + 1} is selected)",
            state.selected_index,
        )
    if at_end and not may_follow(statement, unknown := state.unknown_pose):
        return Refusal(Rule.INSERT_AFTER_TASK, why_not(statement, unknown), state.empty_index - 1)
    return None


def strict_delete(state: ProgramState, first: int, stop: int) -> Refusal | None:
    """Statements ``first..stop`` (real ones, both included) may go when nothing but the empty
    statement follows them, or when they hold no motion (a task that moves the arm counts only
    when a motion follows it)."""
    statements = state.statements
    if stop == state.empty_index - 1:
        return None  # nothing but the empty statement follows: continuity is kept
    motion_after = any(moves_arm(s) for s in statements[stop + 1 :])
    for index in range(first, stop + 1):
        st = statements[index]
        if is_task(st) and moves_arm(st) and motion_after:
            return Refusal(
                Rule.DELETE_ACTION_NOT_LAST,
                f"TASK {st.name} (statement {index + 1}) moves the arm and a motion follows it; "
                "deleting it would break action continuity (delete the motions after it first)",
                index,
            )
    actions = [i for i in range(first, stop + 1) if is_action(statements[i])]
    if not actions:
        return None  # parameter statements and tasks that keep the arm still may go anywhere
    index = actions[0]
    kind = statements[index].kind
    if first == stop:
        message = (
            f"the {kind} action (statement {index + 1}) is not just before the trailing empty statement; "
            "deleting it would break action continuity"
        )
    else:
        message = (
            f"statements {first + 1}..{stop + 1} hold the {kind} action (statement {index + 1}) and statement "
            f"{stop + 2} follows them; deleting actions with statements after them would break action continuity "
            "(delete a range that reaches the end, or parameter statements only)"
        )
    return Refusal(Rule.DELETE_ACTION_NOT_LAST, message, index)


def strict_modify(state: ProgramState, statement: object) -> Refusal | None:
    """Anything but a task call, kept to its kind; an action's own parameters only for the
    action just before the trailing empty statement."""
    index = state.selected_index
    old = state.statements[index]
    if is_task(old):
        return Refusal(Rule.MODIFY_TASK, f"the task call {old.name!r} cannot be modified; delete it instead", index)
    if not is_real(statement) or statement.kind != old.kind:
        return Refusal(
            Rule.MODIFY_KIND,
            f"a modification keeps the statement's kind: statement {index + 1} is {old.kind}, not {describe(statement)}",
            index,
        )
    if is_action(old) and index != state.empty_index - 1 and action_body(statement) != action_body(old):
        return Refusal(
            Rule.MODIFY_ACTION_PARAMETERS,
            f"only the WITH and UNTIL conditions of the {old.kind} action (statement {index + 1}) can change; "
            "its own parameters can change only when it is just before the trailing empty statement "
            "(action continuity)",
            index,
        )
    return None


def strict_move(state: ProgramState, first: int, stop: int) -> Refusal | None:
    """A move is a delete and an insert: under the thesis's rules only statements that change no
    motion (parameter statements, tasks that keep the arm still) can take another place."""
    for index in range(first, stop + 1):
        st = state.statements[index]
        if moves_arm(st):
            what = f"TASK {st.name}" if is_task(st) else f"the {st.kind} action"
            return Refusal(
                Rule.MOVE_MOTION,
                f"{what} (statement {index + 1}) moves the arm; under the thesis's editing rules only parameter "
                "statements and tasks that keep the arm still can be moved (free editing moves any statement)",
                index,
            )
    return None
