"""Free editing: any statement or range may be deleted, replaced, moved or inserted anywhere.

Why it is safe: every action names only its absolute target (a joint vector, a tool pose in a
named frame), so a statement always starts where the one before it ends, whatever that is now;
deleting a motion in the middle means the next one starts where the one before the deleted one
ended, and the planner plans it from there. Continuity holds by construction. What an edit can
still break is what the program *needs* along the way, and the editor refuses an edit only for
that, checking the result:

* the task rule (``shared.language.task_rule``): nothing that moves the arm may follow a task call
  whose end pose only the robot knows (``edit.after-task``); a program never breaks it, so any
  break is the edit's;
* the gripper state later task calls need (``edit.task-state``): ``extract_peg`` and ``release``
  need the gripper holding, ``grasp`` needs it empty. Where the program starts the editor does not
  know what the gripper holds, so it tries both (empty, holding something) and refuses an edit only
  when, under every start the program was consistent with before, a task call the edit did not
  touch would find the gripper wrong;
* the path of the statements after the edit (``edit.path``): re-planned and checked for joint
  limits and collisions by the console (``server.console.program_desk``), which knows the robot
  and the cell; this module has neither.

Only what the edit *breaks* is refused: a statement that could not run before the edit does not
stop the operator from editing around it (an edit is often how it gets fixed).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from shared.language.statements import Statement, is_task
from shared.language.tasks import TASKS
from shared.program import marks
from shared.program.rules import Refusal, Rule

_SOMETHING = object()
"""Start assumption: the gripper holds an object the program does not name yet."""
_STARTS = (None, _SOMETHING)
"""What the gripper may hold where the program starts: nothing, or an object not named yet."""


def gripper_breaks(statements: Sequence[object], start: object = None, tasks: Iterable[int] | None = None) -> dict[int, str]:
    """Task calls (index -> why) that would find the gripper wrong, from ``start``: ``None`` (the
    gripper empty), an object's name, or ``_SOMETHING`` (holding an object not named yet).
    Names compare without case, as the cell resolves them. ``tasks``: where the task calls are
    (``marks.task_indices``), when known; only those statements are read."""
    holding = start
    breaks: dict[int, str] = {}
    for index in range(len(statements)) if tasks is None else tasks:
        st = statements[index]
        if not is_task(st):
            continue
        spec = TASKS.get(st.name) or TASKS.get(st.name.lower())
        if spec is None or spec.needs_holding is None:
            continue
        arg = st.args[0] if st.args and spec.params else None
        if spec.needs_holding is False:
            if holding is not None:
                breaks[index] = f"the gripper would already hold {_name(holding)}"
            holding = arg if arg is not None else _SOMETHING
            continue
        if holding is None:
            breaks[index] = "the gripper would hold nothing"
        elif arg is not None and holding is not _SOMETHING and arg.lower() != str(holding).lower():
            breaks[index] = f"the gripper would hold {holding}, not {arg}"
        elif holding is _SOMETHING and arg is not None:
            holding = arg
        if spec.name == "release":
            holding = None
    return breaks


def _name(holding: object) -> str:
    return "an object" if holding is _SOMETHING else str(holding)


def _what(statement: object) -> str:
    return f"TASK {statement.name}" if is_task(statement) else f"a {getattr(statement, 'kind', '?')}"


@dataclass(frozen=True)
class EditMap:
    """How an edit turned ``before`` into ``after``: the statements' marks on both sides
    (``shared.program.marks``), the first entry that differs, and for each entry of ``after``
    the entry of ``before`` it was (``None``: the edit put it in). The editor builds one from the
    edit it makes, so checking an edit reads no more of the program than the edit changed."""

    before_marks: np.ndarray
    after_marks: np.ndarray
    first: int
    old_of: Callable[[int], int | None]
    keeps_rest: bool
    """Whether a statement that was there before comes at or after ``first``."""

    @classmethod
    def splice(cls, before_marks: np.ndarray, inserted: np.ndarray, first: int, stop: int) -> EditMap:
        """``before[first:stop]`` replaced by statements with marks ``inserted``."""
        n_in, shift = len(inserted), len(inserted) - (stop - first)

        def old_of(i: int) -> int | None:
            return i if i < first else None if i < first + n_in else i - shift

        return cls(before_marks, marks.splice(before_marks, first, stop, inserted), first, old_of, stop < len(before_marks))

    @classmethod
    def move(cls, before_marks: np.ndarray, first: int, stop: int, by: int) -> EditMap:
        """Entries ``first..stop`` (both included) moved ``by`` places."""
        size, at = stop - first + 1, first + by

        def old_of(i: int) -> int | None:
            if at <= i < at + size:
                return first + (i - at)
            rest = i if i < at else i - size  # the index among the statements not moved
            return rest if rest < first else rest + size

        return cls(before_marks, marks.moved(before_marks, first, stop, by), min(first, at), old_of, True)

    @classmethod
    def by_identity(cls, before: Sequence[Statement], after: Sequence[Statement]) -> EditMap:
        """Found by comparing the two programs statement by statement (for a caller that has no
        edit to describe; reads both programs whole)."""
        old_index = {id(s): i for i, s in enumerate(before)}
        first = next((i for i, (a, b) in enumerate(zip(before, after)) if a is not b), min(len(before), len(after)))
        keeps = any(id(s) in old_index for s in after[first:])
        return cls(marks.marks_of(before), marks.marks_of(after), first, lambda i: old_index.get(id(after[i])), keeps)


def free_edit_refusal(before: Sequence[Statement], after: Sequence[Statement], where: int,
                      edit: EditMap | None = None) -> Refusal | None:
    """Why the program ``after`` (an edit of ``before``, described by ``edit`` when the caller
    knows it) cannot run where ``before`` could, or ``None``. ``where``: the entry the edit acts
    on, where a refusal about a statement the edit itself put in is shown. A refusal about a
    statement that was there before is shown on that statement's line, numbered as the operator
    sees it now (in ``before``)."""
    edit = edit or EditMap.by_identity(before, after)

    def shown_at(index: int) -> int:
        old = edit.old_of(index)
        return where if old is None else old

    b = marks.first_break(after, edit.after_marks)
    if b is not None:
        st = after[b.index]
        return Refusal(
            Rule.EDIT_AFTER_TASK,
            f"after this edit {_what(st)} would follow TASK {b.after.task}, whose end pose only the robot knows: "
            "only parameter statements and tasks that keep the arm still may follow it",
            shown_at(b.index),
        )
    if not edit.keeps_rest:
        return None  # nothing that was there before comes after the edit: nothing else to break
    tasks_before, tasks_after = marks.task_indices(edit.before_marks), marks.task_indices(edit.after_marks)
    before_breaks = {start: gripper_breaks(before, start, tasks_before) for start in _STARTS}
    starts = [start for start in _STARTS if not before_breaks[start]] or list(_STARTS)
    found: tuple[int, str] | None = None
    for start in starts:
        broken_before = set(before_breaks[start])
        new = [
            (i, why) for i, why in sorted(gripper_breaks(after, start, tasks_after).items())
            if (old := edit.old_of(i)) is not None and old not in broken_before
        ]
        if not new:
            return None  # the program still runs from a start it ran from before
        found = found or new[0]
    assert found is not None
    index, why = found
    line = shown_at(index)
    return Refusal(
        Rule.EDIT_TASK_STATE,
        f"TASK {after[index].name} (statement {line + 1}) could no longer run after this edit: {why} there",
        line,
    )
