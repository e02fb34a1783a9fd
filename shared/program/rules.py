"""The program-management rules of thesis §4.3.6, each with an id, and the typed refusal.

Why a rule list of its own: the editor refuses many operations, and the console must tell the
operator *which* rule stood in the way (a greyed button with a reason, a refusal line in the
log). Every refusal therefore names one :class:`Rule`; the ids are stable strings the web page
and the tests can rely on.

The rules, as §4.3.6 states them (2) "语句管理规则", 3) preview, 4) submit):

* The program is real statements followed by exactly one empty statement, at the end.
* Exactly one statement is selected; by default the trailing empty one. Inserting and modifying
  leave the selection on the same statement; deleting moves it to the next statement.
* Insertion puts a new *real* statement before the selected one. Action and task-call statements
  only before the trailing empty statement; parameter statements before any statement. After a
  task call whose end pose only the robot knows (``insert_peg``), only statements that leave the
  arm where it is may follow: parameter statements and tasks that keep the arm still
  (``shared.language.task_rule``: the task registry's end-state contracts, the rule ``teleprog
  check`` and the planner apply too; the thesis's literal "nothing after a task call" is
  ``teleprog check --strict-tasks``).
* Any selected statement but the trailing empty one may be deleted; an action only when it is
  the statement just before the trailing empty one; parameter statements anywhere.
* Anything but a task call or the empty statement may be modified: parameter statements
  anywhere; the conditions of an action (WITH speed, UNTIL stop) anywhere; the action's own
  parameters only for the action just before the trailing empty statement.
* No operation may break action continuity (each action starts where the previous one ends).
  The rules above are what guarantees it: statements name only their target, so the start of an
  action is the end of the motion before it, and only the last motion may change.
* While a preview runs, only selection is allowed.
* Submitted statements leave the program. Only a prefix may be submitted (the robot then
  continues from where the last submitted statement leaves it, which is where the next
  remaining action starts); submitted statements cannot be taken back by undo.

These are the rules of the *strict* mode (``Editor(strict=True)``; in the console
``SessionSettings.strict_editing``, the Program tab's box, ``PUT /api/program/editing``). The
default is *free* editing (``shared.program.free_rules``): every action
names only its absolute target, so any statement or range may be deleted, replaced, moved or
inserted anywhere, and the statement after an edit simply starts where the one before it now
ends. A free edit is refused only when its result cannot run: a motion after a task whose end
pose only the robot knows (``edit.after-task``), a later task whose gripper state the edit breaks
(``edit.task-state``), or, checked by the console against the robot and the cell, a statement
after the edit that could no longer be planned, or would leave a joint range or collide
(``edit.path``). The rule ids are for the API and tooltips; the sentences are for the operator.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from typing import TypeVar

from shared.errors import InputError
from shared.language.statements import Statement, is_action, is_parameter, is_task
from shared.language.task_rule import task_rule_breaks


class Rule(str, Enum):
    """One rule of §4.3.6 (or of the editor's history); the value is the stable id."""

    SELECT_RANGE = "select.range"
    """The selection must be one of the program's statements (the empty one included)."""

    PREVIEW_LOCKED = "preview.locked"
    """While a preview runs, every operation but selection is refused (§4.3.6 3)."""
    PREVIEW_RANGE = "preview.range"
    """A preview plays a non-empty range of real statements."""
    PREVIEW_INACTIVE = "preview.inactive"
    """Ending a preview needs a preview to be running."""

    INSERT_REAL = "insert.real"
    """Only a real statement (action, parameter, task call) can be inserted."""
    INSERT_ACTION_AT_END = "insert.action-at-end"
    """An action statement can only be inserted before the trailing empty statement."""
    INSERT_TASK_AT_END = "insert.task-at-end"
    """A task call can only be inserted before the trailing empty statement."""
    INSERT_AFTER_TASK = "insert.after-task"
    """Nothing that moves the arm can be inserted after a task call whose end pose is unknown."""

    DELETE_EMPTY = "delete.empty"
    """The trailing empty statement cannot be deleted."""
    DELETE_ACTION_NOT_LAST = "delete.action-not-last"
    """An action can be deleted only when it is just before the trailing empty statement."""

    MODIFY_EMPTY = "modify.empty"
    """The trailing empty statement cannot be modified."""
    MODIFY_TASK = "modify.task"
    """A task call cannot be modified."""
    MODIFY_KIND = "modify.kind"
    """A modification keeps the statement's kind (delete and insert to change it)."""
    MODIFY_ACTION_PARAMETERS = "modify.action-parameters"
    """An action's own parameters can be changed only for the action just before the empty one."""
    MODIFY_CONDITIONS_NOT_ACTION = "modify.conditions-not-action"
    """WITH / UNTIL conditions belong to action statements only."""

    SUBMIT_RANGE = "submit.range"
    """A submission is a non-empty range of real statements."""
    SUBMIT_PREFIX = "submit.prefix"
    """Only a prefix of the program can be submitted (continuity with what the robot has)."""

    UNDO_NOTHING = "undo.nothing"
    """There is no operation to undo."""
    UNDO_SUBMITTED = "undo.submitted"
    """Operations before a submission cannot be undone: the robot already has those statements."""
    REDO_NOTHING = "redo.nothing"
    """There is no undone operation to redo."""

    PROGRAM_AFTER_TASK = "program.after-task"
    """In a program, nothing that moves the arm may follow a task call whose end pose is unknown."""

    MOVE_RANGE = "move.range"
    """A move shifts real statements within the program (not past its ends, not the empty one)."""
    MOVE_MOTION = "move.motion"
    """Strict mode: only parameter statements and tasks that keep the arm still can be moved."""

    EDIT_AFTER_TASK = "edit.after-task"
    """Free mode: the edit would put a motion after a task call whose end pose is unknown."""
    EDIT_TASK_STATE = "edit.task-state"
    """Free mode: the edit would break the gripper state a later task call needs."""
    EDIT_PATH = "edit.path"
    """Free mode: a statement after the edit could no longer run (the console re-plans the rest)."""


@dataclass(frozen=True, slots=True)
class Refusal:
    """An operation the rules do not allow: which rule, and a sentence for the operator."""

    rule: Rule
    message: str
    index: int | None = None
    """The statement the rule concerns (0-based, as in the program's entries), where it has one:
    the page shows the refusal under that line."""

    def __str__(self) -> str:
        return f"refused by rule {self.rule.value}: {self.message}"


class RefusedError(InputError):
    """Raised by :func:`unwrap` for callers (API, CLI) that prefer an exception to a value."""

    def __init__(self, refusal: Refusal) -> None:
        self.refusal = refusal
        super().__init__(str(refusal))


T = TypeVar("T")


def unwrap(result: T | Refusal) -> T:
    """The result of an operation, or :class:`RefusedError` if it was refused."""
    if isinstance(result, Refusal):
        raise RefusedError(result)
    return result


def is_real(statement: object) -> bool:
    """An action, a parameter statement or a task call: what a program holds."""
    return is_action(statement) or is_parameter(statement) or is_task(statement)


def action_body(statement: Statement) -> Statement:
    """The action without its conditions: what §4.3.6 calls the action's own parameters."""
    return statement.model_copy(update={"speed": None, "until": None})


def describe(statement: object) -> str:
    """A statement's kind (``DRAW``), or the type of something that is not one."""
    return getattr(statement, "kind", type(statement).__name__)


@dataclass(frozen=True, slots=True)
class Violation:
    """A rule a whole program breaks, at a statement index (0-based)."""

    index: int
    rule: Rule
    message: str


def program_violations(statements: Sequence[object]) -> list[Violation]:
    """Rules a program given as a whole (read from a file, received) breaks.

    Only one rule constrains a bare list of statements: what may follow a task call
    (``shared.language.task_rule``, the same rule ``teleprog check`` and the planner apply).
    Continuity holds by construction in a list of target-only statements; the other rules are
    about editing operations.
    """
    return [Violation(b.index, Rule.PROGRAM_AFTER_TASK, b.message) for b in task_rule_breaks(statements)]
