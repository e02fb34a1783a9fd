"""The program editor of thesis §4.3.6 as a pure, typed state machine.

:class:`ProgramState` is an immutable value: the real statements, which one is selected, and
whether a preview is running. Every operation is a method that returns either a new state (or a
small result holding one) or a :class:`~shared.program.rules.Refusal` naming the rule that
stood in the way; the old state is never changed. :class:`Editor` holds the current state and
the undo/redo history, so the console keeps one per operator and the robot never sees it.

Why this shape: the console, its tests and a replay of an operator session all need the same
answer to "may I do this here?", and an immutable state makes undo exact (the history holds the
very states, not inverse operations that could drift).

Representation: the trailing empty statement is not stored; ``statements`` holds the real
statements and the empty one sits at index ``len(statements)``. ``entries`` shows the program
the way §4.3.6 describes it, empty statement included. Indices in the API are 0-based; the
sentences of refusals number statements from 1, as the operator sees them.

Two modes, chosen per editor (``Editor(strict=...)``, switchable at any time, not an edit):

* *free* (the default, ``shared.program.free_rules``): any statement or range may be deleted,
  replaced (by a statement of any kind), moved or inserted anywhere; every action names only its
  absolute target, so the statement after an edit simply starts where the one before it now ends.
  An edit is refused only when its result cannot run (a motion after a task whose end pose is
  unknown, a later task call's gripper state broken; the console adds the re-planned path);
* *strict* (``shared.program.strict_rules``): the rules of thesis §4.3.6 as the thesis states
  them, which keep continuity without knowing any robot state by letting only the last motion
  change.

Selection is a range: ``selected`` is the cursor (where insert and modify act, as in §4.3.6) and
``anchor``, when set, the other end of a range (a shift-click or shift-arrow in the page). A range
delete or move is one edit, one undo step. Every refusal names the statement it concerns
(``Refusal.index``) where it has one, so the page shows it on its line.

The order in which an operation's rules are tested (and so which rule a refusal names when
several apply) is: preview lock, then what the selected statement is, then what the new
statement is, then where it is.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Final

import numpy as np

from shared.errors import InputError
from shared.language.statements import Speed, Statement, Until, is_action, is_task
from shared.language.task_rule import UnknownPose, may_follow, why_not
from shared.program import marks as kinds
from shared.program.free_rules import EditMap, free_edit_refusal
from shared.program.rules import Refusal, Rule, describe, is_real
from shared.program.strict_rules import strict_delete, strict_insert, strict_modify, strict_move

log = logging.getLogger(__name__)

__all__ = [
    "EMPTY",
    "KEEP",
    "Editor",
    "EmptyStatement",
    "PreviewStarted",
    "ProgramState",
    "Refusal",
    "Rule",
    "Submission",
]


@dataclass(frozen=True, slots=True)
class EmptyStatement:
    """The statement that holds no information; every program ends with exactly one."""

    kind: str = "EMPTY"

    def __repr__(self) -> str:
        return "EMPTY"


EMPTY: Final = EmptyStatement()


class _Keep:
    """Marker for "leave this condition as it is" in :meth:`ProgramState.modify_conditions`."""

    _instance: _Keep | None = None

    def __new__(cls) -> _Keep:
        if cls._instance is None:
            cls._instance = super().__new__(cls)
        return cls._instance

    def __repr__(self) -> str:
        return "KEEP"


KEEP: Final = _Keep()


@dataclass(frozen=True, slots=True)
class Submission:
    """What a submission hands over: the statements for the robot, and the program left."""

    statements: tuple[Statement, ...]
    state: ProgramState


@dataclass(frozen=True, slots=True)
class PreviewStarted:
    """A preview of ``statements[start:stop]``; ``state`` is locked until :meth:`end_preview`."""

    start: int
    stop: int
    statements: tuple[Statement, ...]
    state: ProgramState


@dataclass(frozen=True, slots=True)
class ProgramState:
    """The program being edited: real statements, then the implicit trailing empty statement.

    ``selected`` is an index into :attr:`entries` (``len(statements)`` is the empty statement,
    the default). ``preview`` is the ``(start, stop)`` range being previewed, or ``None``.
    Construction checks the invariants and raises :class:`~shared.errors.InputError` on a
    program that breaks them (a statement after a task call, a selection out of range).
    """

    statements: tuple[Statement, ...] = ()
    selected: int | None = None
    preview: tuple[int, int] | None = None
    anchor: int | None = None
    """The other end of a selected range (``None``: only ``selected`` is selected)."""
    marks: np.ndarray | None = field(default=None, compare=False, repr=False)
    """Each statement's kind as bits (``shared.program.marks``): read from the statements when not
    given; the editor's operations splice the state's own, so an edit reads what it changed."""

    def __post_init__(self) -> None:
        statements = tuple(self.statements)
        object.__setattr__(self, "statements", statements)
        marks = self.marks
        if marks is None or len(marks) != len(statements):
            marks = kinds.marks_of(statements)
            object.__setattr__(self, "marks", marks)
        if (index := kinds.first_not_real(marks)) is not None:
            raise InputError(
                f"statement {index + 1}: a program holds real statements only, got {describe(statements[index])}"
            )
        if (broken := kinds.first_break(statements, marks)) is not None:
            raise InputError(broken.message)
        if self.selected is None:
            object.__setattr__(self, "selected", len(statements))
        elif not 0 <= self.selected <= len(statements):
            raise InputError(f"selection {self.selected} is outside the program (0..{len(statements)})")
        if self.anchor is not None and not 0 <= self.anchor <= len(statements):
            raise InputError(f"selection anchor {self.anchor} is outside the program (0..{len(statements)})")
        if self.anchor == self.selected:
            object.__setattr__(self, "anchor", None)
        if self.preview is not None:
            start, stop = self.preview
            if not 0 <= start < stop <= len(statements):
                raise InputError(f"preview range {start}..{stop} is outside the program")

    # ---------------------------------------------------------------- reading

    @classmethod
    def of(cls, statements: Iterable[Statement], selected: int | None = None) -> ProgramState:
        """A program from a list of statements (the empty statement is added), selection default."""
        return cls(tuple(statements), selected)

    @property
    def entries(self) -> tuple[Statement | EmptyStatement, ...]:
        """The program as §4.3.6 describes it: real statements, then the one empty statement."""
        return (*self.statements, EMPTY)

    @property
    def empty_index(self) -> int:
        """Index of the trailing empty statement."""
        return len(self.statements)

    @property
    def selected_index(self) -> int:
        assert self.selected is not None  # set in __post_init__
        return self.selected

    @property
    def selected_range(self) -> tuple[int, int]:
        """The selected entries ``(first, last)``, both included (one entry: ``first == last``)."""
        if self.anchor is None:
            return self.selected_index, self.selected_index
        return min(self.anchor, self.selected_index), max(self.anchor, self.selected_index)

    @property
    def selected_statement(self) -> Statement | EmptyStatement:
        return self.entries[self.selected_index]

    @property
    def previewing(self) -> bool:
        return self.preview is not None

    @property
    def ends_with_task(self) -> bool:
        """True when the last real statement is a task call."""
        return bool(self.statements) and is_task(self.statements[-1])

    @property
    def unknown_pose(self) -> UnknownPose | None:
        """The task call after which the arm's pose is unknown (only what keeps the arm still may
        follow it: ``shared.language.task_rule``), or ``None`` when the pose is known throughout."""
        return kinds.unknown_pose(self.statements, self._marks)

    # ---------------------------------------------------------------- selection

    def select(self, index: int, *, extend: bool = False) -> ProgramState | Refusal:
        """Select the statement at ``index`` (the empty statement is ``len(statements)``);
        ``extend``: the range from the current anchor (or the current selection) to ``index``."""
        if (outside := self._outside(index)) is not None:
            return outside
        return self._with(selected=index, anchor=self._anchor_for(extend))

    def select_range(self, first: int, last: int) -> ProgramState | Refusal:
        """Select entries ``first..last`` (both included); the cursor goes to ``last``."""
        for index in (first, last):
            if (outside := self._outside(index)) is not None:
                return outside
        return self._with(selected=last, anchor=first)

    def select_next(self, *, extend: bool = False) -> ProgramState | Refusal:
        if self.selected_index == self.empty_index:
            return Refusal(Rule.SELECT_RANGE, "the trailing empty statement is selected; nothing follows it")
        return self._with(selected=self.selected_index + 1, anchor=self._anchor_for(extend))

    def select_previous(self, *, extend: bool = False) -> ProgramState | Refusal:
        if self.selected_index == 0:
            return Refusal(Rule.SELECT_RANGE, "the first statement is selected; nothing precedes it")
        return self._with(selected=self.selected_index - 1, anchor=self._anchor_for(extend))

    def select_first(self) -> ProgramState:
        return self._with(selected=0)

    def select_empty(self) -> ProgramState:
        """Select the trailing empty statement (the default selection)."""
        return self._with(selected=self.empty_index)

    # ---------------------------------------------------------------- checks

    def check_insert(self, statement: object, *, strict: bool = False) -> Refusal | None:
        """Why ``statement`` cannot be inserted before the selection, or ``None`` if it can."""
        if (locked := self._locked("insert a statement")) is not None:
            return locked
        if not is_real(statement):
            return Refusal(
                Rule.INSERT_REAL, f"only a real statement can be inserted, not {describe(statement)}", self.selected_index
            )
        if strict:
            return strict_insert(self, statement)
        index = self.selected_index
        if index == self.empty_index:  # at the end: only the task rule can refuse it
            unknown = self.unknown_pose
            return None if may_follow(statement, unknown) else Refusal(Rule.INSERT_AFTER_TASK, why_not(statement, unknown), index - 1)
        return self._free(self._splice(index, index, (statement,)), index)

    def check_delete(self, first: int | None = None, last: int | None = None, *, strict: bool = False) -> Refusal | None:
        """Why entries ``first..last`` (both included; default: the selected range) cannot be
        deleted, or ``None`` if they can. The trailing empty statement in the range stays."""
        if (locked := self._locked("delete a statement")) is not None:
            return locked
        if first is None or last is None:
            first, last = self.selected_range
        if first > last:
            first, last = last, first
        for index in (first, last):
            if (outside := self._outside(index)) is not None:
                return outside
        if first == self.empty_index:
            return Refusal(Rule.DELETE_EMPTY, "the trailing empty statement cannot be deleted", first)
        stop = min(last, self.empty_index - 1)  # the last real statement deleted
        if strict:
            return strict_delete(self, first, stop)
        return self._free(self._splice(first, stop + 1, ()), first)

    def check_modify(self, statement: object, *, strict: bool = False) -> Refusal | None:
        """Why the selected statement cannot be replaced by ``statement``, or ``None`` if it can."""
        if (locked := self._locked("modify a statement")) is not None:
            return locked
        index = self.selected_index
        if index == self.empty_index:
            return Refusal(Rule.MODIFY_EMPTY, "the trailing empty statement cannot be modified; insert instead", index)
        if strict:
            return strict_modify(self, statement)
        if not is_real(statement):
            return Refusal(
                Rule.MODIFY_KIND,
                f"statement {index + 1} can only be replaced by a statement (an action, a parameter statement or a "
                f"task call), not {describe(statement)}",
                index,
            )
        return self._free(self._splice(index, index + 1, (statement,)), index)

    def check_move(self, by: int, *, strict: bool = False) -> Refusal | None:
        """Why the selected range (its real statements) cannot move ``by`` places (negative: up),
        or ``None`` if it can."""
        if (locked := self._locked("move statements")) is not None:
            return locked
        first, last = self.selected_range
        stop = min(last, self.empty_index - 1)
        if first > stop or by == 0 or not 0 <= first + by <= stop + by < self.empty_index:
            what = "the trailing empty statement" if first > stop else f"statements {first + 1}..{stop + 1}"
            return Refusal(
                Rule.MOVE_RANGE,
                f"cannot move {what} by {by}: statements move among the {self.empty_index} real statement(s), "
                "the trailing empty statement stays last",
                first,
            )
        if strict:
            return strict_move(self, first, stop)
        return self._free((self._moved(first, stop, by), EditMap.move(self._marks, first, stop, by)), first)

    def check_submit(self, start: int, stop: int) -> Refusal | None:
        """Why ``statements[start:stop]`` cannot be submitted, or ``None`` if it can."""
        if (locked := self._locked("submit statements")) is not None:
            return locked
        if not 0 <= start < stop <= self.empty_index:
            return Refusal(
                Rule.SUBMIT_RANGE,
                f"cannot submit {start}..{stop}: a submission is a non-empty range within the "
                f"{self.empty_index} real statement(s)",
                start if 0 <= start <= self.empty_index else None,
            )
        if start != 0:
            return Refusal(
                Rule.SUBMIT_PREFIX,
                f"cannot submit from statement {start + 1}: it starts where statement {start} ends, and the robot "
                f"has not been sent statements 1..{start} yet; a submission starts at statement 1 so that the robot "
                f"continues from where it already is (submit 1..{stop} instead)",
                start,
            )
        return None

    # ---------------------------------------------------------------- operations

    def insert(self, statement: Statement, *, strict: bool = False) -> ProgramState | Refusal:
        """Insert ``statement`` before the selected one; the selection stays on the same statement."""
        if (refusal := self.check_insert(statement, strict=strict)) is not None:
            return refusal
        index = self.selected_index
        statements, edit = self._splice(index, index, (statement,))
        return self._with(statements=statements, marks=edit.after_marks, selected=index + 1)

    def delete(self, first: int | None = None, last: int | None = None, *, strict: bool = False) -> ProgramState | Refusal:
        """Delete entries ``first..last`` (default: the selected range; the trailing empty
        statement stays); the selection moves to the statement after the deleted range."""
        if first is None or last is None:
            first, last = self.selected_range
        if first > last:
            first, last = last, first
        if (refusal := self.check_delete(first, last, strict=strict)) is not None:
            return refusal
        stop = min(last, self.empty_index - 1) + 1
        statements, edit = self._splice(first, stop, ())
        return self._with(statements=statements, marks=edit.after_marks, selected=first)

    def modify(self, statement: Statement, *, strict: bool = False) -> ProgramState | Refusal:
        """Replace the selected statement by ``statement`` (strict: of the same kind); the selection is kept."""
        if (refusal := self.check_modify(statement, strict=strict)) is not None:
            return refusal
        index = self.selected_index
        statements, edit = self._splice(index, index + 1, (statement,))
        return self._with(statements=statements, marks=edit.after_marks)

    def move(self, by: int, *, strict: bool = False) -> ProgramState | Refusal:
        """Move the selected range's statements ``by`` places (negative: up); the selection moves with them."""
        if (refusal := self.check_move(by, strict=strict)) is not None:
            return refusal
        first, last = self.selected_range
        stop = min(last, self.empty_index - 1)
        cursor = min(self.selected_index, stop) + by
        anchor = None if self.anchor is None else min(self.anchor, stop) + by
        return self._with(statements=self._moved(first, stop, by), marks=kinds.moved(self._marks, first, stop, by),
                          selected=cursor, anchor=anchor)

    def modify_conditions(
        self, speed: Speed | None | _Keep = KEEP, until: Until | None | _Keep = KEEP, *, strict: bool = False
    ) -> ProgramState | Refusal:
        """Set or clear (``None``) the WITH speed and UNTIL condition of the selected action.

        Allowed for an action anywhere in the program (§4.3.6 2d). ``KEEP`` leaves one as it is.
        """
        if (locked := self._locked("modify a statement")) is not None:
            return locked
        old = self.selected_statement
        if not is_action(old):
            if old is EMPTY:
                return Refusal(Rule.MODIFY_EMPTY, "the trailing empty statement cannot be modified", self.selected_index)
            return Refusal(
                Rule.MODIFY_CONDITIONS_NOT_ACTION,
                f"WITH and UNTIL belong to action statements; statement {self.selected_index + 1} is {old.kind}",
                self.selected_index,
            )
        fields = dict(old)
        if speed is not KEEP:
            fields["speed"] = speed
        if until is not KEEP:
            fields["until"] = until
        return self.modify(type(old)(**fields), strict=strict)

    def submit(self, start: int, stop: int) -> Submission | Refusal:
        """Take ``statements[start:stop]`` out of the program for the robot; ``start`` must be 0.

        The selection stays on the same statement; if that statement was submitted, it moves to
        the first statement left (as after a deletion).
        """
        if (refusal := self.check_submit(start, stop)) is not None:
            return refusal
        rest = self.statements[stop:]
        left = self._with(statements=rest, marks=self._marks[stop:], selected=max(self.selected_index - stop, 0))
        return Submission(self.statements[start:stop], left)

    def submit_through(self, last: int) -> Submission | Refusal:
        """Submit statements ``0..last`` inclusive (the console's "send up to here")."""
        return self.submit(0, last + 1)

    def begin_preview(self, start: int, stop: int) -> PreviewStarted | Refusal:
        """Lock the program while ``statements[start:stop]`` is played; the program is unchanged."""
        if self.preview is not None:
            return Refusal(Rule.PREVIEW_LOCKED, "a preview is already running; end it first")
        if not 0 <= start < stop <= self.empty_index:
            return Refusal(
                Rule.PREVIEW_RANGE,
                f"cannot preview {start}..{stop}: a preview plays a non-empty range within the "
                f"{self.empty_index} real statement(s)",
            )
        return PreviewStarted(start, stop, self.statements[start:stop], self._with(preview=(start, stop)))

    def end_preview(self) -> ProgramState | Refusal:
        if self.preview is None:
            return Refusal(Rule.PREVIEW_INACTIVE, "no preview is running")
        return self._with(preview=None)

    # ---------------------------------------------------------------- helpers

    def _locked(self, what: str) -> Refusal | None:
        if self.preview is None:
            return None
        start, stop = self.preview
        return Refusal(
            Rule.PREVIEW_LOCKED,
            f"cannot {what} while statements {start + 1}..{stop} are being previewed; only selection is allowed",
        )

    def _free(self, edited: tuple[tuple[Statement, ...], EditMap], where: int) -> Refusal | None:
        """Free mode: why the edited program (its statements and how the edit made them) cannot
        run where this one could."""
        statements, edit = edited
        return free_edit_refusal(self.statements, statements, where, edit)

    @property
    def _marks(self) -> np.ndarray:
        assert self.marks is not None  # set in __post_init__
        return self.marks

    def _splice(self, first: int, stop: int, inserted: tuple[Statement, ...]) -> tuple[tuple[Statement, ...], EditMap]:
        """The statements with ``statements[first:stop]`` replaced by ``inserted``, and the edit's map."""
        edit = EditMap.splice(self._marks, kinds.marks_of(inserted), first, stop)
        return (*self.statements[:first], *inserted, *self.statements[stop:]), edit

    def _moved(self, first: int, stop: int, by: int) -> tuple[Statement, ...]:
        """The statements with ``first..stop`` (both included) moved ``by`` places."""
        block = self.statements[first : stop + 1]
        rest = self.statements[:first] + self.statements[stop + 1 :]
        at = first + by
        return (*rest[:at], *block, *rest[at:])

    def _outside(self, index: int) -> Refusal | None:
        if 0 <= index <= self.empty_index:
            return None
        return Refusal(
            Rule.SELECT_RANGE,
            f"index {index} is outside the program: entries are 0..{self.empty_index} "
            "(the last is the empty statement)",
        )

    def _anchor_for(self, extend: bool) -> int | None:
        """The anchor of a selection move: kept (or set at the cursor) when extending, else none."""
        if not extend:
            return None
        return self.anchor if self.anchor is not None else self.selected_index

    def _with(self, **changes: object) -> ProgramState:
        """A copy with ``changes``; a change of the statements or of the cursor drops the range
        unless the change names its anchor."""
        values = {"statements": self.statements, "selected": self.selected, "preview": self.preview, "anchor": self.anchor,
                  "marks": self.marks}
        if ("statements" in changes or "selected" in changes) and "anchor" not in changes:
            values["anchor"] = None
        if "statements" in changes and "marks" not in changes:
            values["marks"] = None  # read from the new statements
        values.update(changes)
        return ProgramState(**values)  # type: ignore[arg-type]


@dataclass(frozen=True, slots=True)
class _Step:
    label: str
    before: ProgramState
    after: ProgramState


class Editor:
    """The current :class:`ProgramState` with an undo/redo history of every edit.

    Edits (insert, delete, modify, modify_conditions, move_statements, load) are recorded; undo
    returns to exactly the state before the edit (selection included), redo to exactly the state
    after it. Selection moves, preview start/end and the editing mode are not edits and are not
    recorded. A submission is not undoable (the robot has the statements) and clears the
    history: nothing before it can be undone either, since that would bring submitted statements
    back into the program.

    ``strict``: the thesis's editing rules (§4.3.6, ``shared.program.strict_rules``) instead of
    free editing (``shared.program.free_rules``, the default).
    """

    def __init__(self, state: ProgramState | None = None, max_history: int = 1000, *, strict: bool = False) -> None:
        self._state = state if state is not None else ProgramState()
        self.max_history = max_history
        self.strict = bool(strict)
        self._undo: list[_Step] = []
        self._redo: list[_Step] = []
        self._submitted = False

    @property
    def state(self) -> ProgramState:
        """The current program; it changes only through the operations below."""
        return self._state

    def __repr__(self) -> str:
        mode = "strict" if self.strict else "free"
        return f"Editor({self._state!r}, {mode}, undo={len(self._undo)}, redo={len(self._redo)})"

    # ------------------------------------------------------------ edits

    def insert(self, statement: Statement) -> ProgramState | Refusal:
        return self._edit(f"insert {describe(statement)}", self.state.insert(statement, strict=self.strict))

    def delete(self, first: int | None = None, last: int | None = None) -> ProgramState | Refusal:
        """Delete the selected range (or ``first..last``): one edit, one undo step."""
        if first is None or last is None:
            first, last = self.state.selected_range
        result = self.state.delete(first, last, strict=self.strict)
        if isinstance(result, Refusal):
            return self._refused(result)
        lo = min(first, last)
        count = len(self.state.statements) - len(result.statements)
        label = f"delete {describe(self.state.entries[lo])}" if count == 1 else f"delete statements {lo + 1}..{lo + count}"
        return self._edit(label, result)

    def modify(self, statement: Statement) -> ProgramState | Refusal:
        return self._edit(f"modify {describe(statement)}", self.state.modify(statement, strict=self.strict))

    def modify_conditions(
        self, speed: Speed | None | _Keep = KEEP, until: Until | None | _Keep = KEEP
    ) -> ProgramState | Refusal:
        label = f"modify conditions of {describe(self.state.selected_statement)}"
        return self._edit(label, self.state.modify_conditions(speed, until, strict=self.strict))

    def move_statements(self, by: int) -> ProgramState | Refusal:
        """Move the selected range ``by`` places (negative: up): one edit, one undo step."""
        first, last = self.state.selected_range
        stop = min(last, self.state.empty_index - 1)
        what = f"statement {first + 1}" if first >= stop else f"statements {first + 1}..{stop + 1}"
        direction = "up" if by < 0 else "down"
        return self._edit(f"move {what} {direction}", self.state.move(by, strict=self.strict))

    def load(self, state: ProgramState, label: str = "load program") -> ProgramState | Refusal:
        """Replace the whole program (a file loaded): an edit like any other, so undo brings back
        the program it replaced."""
        if (locked := self.state._locked("load a program")) is not None:
            return self._refused(locked)
        return self._edit(label, state)

    def submit(self, start: int, stop: int) -> Submission | Refusal:
        result = self.state.submit(start, stop)
        if isinstance(result, Refusal):
            return self._refused(result)
        self._state = result.state
        self._undo.clear()
        self._redo.clear()
        self._submitted = True
        log.info("submitted %d statement(s); %d left", len(result.statements), len(result.state.statements))
        return result

    def submit_through(self, last: int) -> Submission | Refusal:
        return self.submit(0, last + 1)

    # ------------------------------------------------------------ not recorded

    def select(self, index: int, *, extend: bool = False) -> ProgramState | Refusal:
        return self._move(self.state.select(index, extend=extend))

    def select_range(self, first: int, last: int) -> ProgramState | Refusal:
        return self._move(self.state.select_range(first, last))

    def select_next(self, *, extend: bool = False) -> ProgramState | Refusal:
        return self._move(self.state.select_next(extend=extend))

    def select_previous(self, *, extend: bool = False) -> ProgramState | Refusal:
        return self._move(self.state.select_previous(extend=extend))

    def select_first(self) -> ProgramState:
        self._state = self.state.select_first()
        return self.state

    def select_empty(self) -> ProgramState:
        self._state = self.state.select_empty()
        return self.state

    def begin_preview(self, start: int, stop: int) -> PreviewStarted | Refusal:
        result = self.state.begin_preview(start, stop)
        if isinstance(result, Refusal):
            return self._refused(result)
        self._state = result.state
        return result

    def end_preview(self) -> ProgramState | Refusal:
        return self._move(self.state.end_preview())

    # ------------------------------------------------------------ history

    @property
    def can_undo(self) -> bool:
        return bool(self._undo) and not self.state.previewing

    @property
    def can_redo(self) -> bool:
        return bool(self._redo) and not self.state.previewing

    @property
    def undo_label(self) -> str | None:
        """What undo would take back (for a menu entry), or ``None``."""
        return self._undo[-1].label if self._undo else None

    @property
    def redo_label(self) -> str | None:
        return self._redo[-1].label if self._redo else None

    def undo(self) -> ProgramState | Refusal:
        """Return to exactly the state before the last edit."""
        if (locked := self.state._locked("undo")) is not None:
            return self._refused(locked)
        if not self._undo:
            if self._submitted:
                return self._refused(
                    Refusal(
                        Rule.UNDO_SUBMITTED,
                        "nothing before the last submission can be undone: the robot has those statements",
                    )
                )
            return self._refused(Refusal(Rule.UNDO_NOTHING, "there is nothing to undo"))
        step = self._undo.pop()
        self._redo.append(step)
        self._state = step.before
        return self.state

    def redo(self) -> ProgramState | Refusal:
        """Return to exactly the state after the last undone edit."""
        if (locked := self.state._locked("redo")) is not None:
            return self._refused(locked)
        if not self._redo:
            return self._refused(Refusal(Rule.REDO_NOTHING, "there is nothing to redo"))
        step = self._redo.pop()
        self._undo.append(step)
        self._state = step.after
        return self.state

    # ------------------------------------------------------------ helpers

    def _edit(self, label: str, result: ProgramState | Refusal) -> ProgramState | Refusal:
        if isinstance(result, Refusal):
            return self._refused(result)
        self._undo.append(_Step(label, self.state, result))
        if len(self._undo) > self.max_history:
            del self._undo[0]
        self._redo.clear()
        self._state = result
        return result

    def _move(self, result: ProgramState | Refusal) -> ProgramState | Refusal:
        if isinstance(result, Refusal):
            return self._refused(result)
        self._state = result
        return result

    @staticmethod
    def _refused(refusal: Refusal) -> Refusal:
        log.debug("%s", refusal)
        return refusal
