"""The program desk (thesis §4.3.4-4.3.6): the program editor and its rules, automatic generation
from the operator's strokes, program files, and where the program starts.

* The editor (``shared.program.editor``) applies every operation on a copy and keeps it only when
  the operation and the program's view both succeed: a refused or failed edit changes nothing.
* Generation (``shared.program.generator``), on from the start (``SessionSettings.auto_generate``):
  every change of the virtual arm is a sample of the operator's stroke; letting go flushes the
  open segment. Cartesian targets are written in the frame the operator jogs in (world, base,
  work; a tool-frame jog writes in the generator's default frame, since a tool-frame target
  depends on where its statement starts). Generated statements go to the program's end; one
  that continues the last generated statement (same joint, same line: the generator says so)
  replaces it while it is still the program's last statement, as one edit with it (undo takes
  the whole stroke back). In the free regime they stream to the robot unless their path is
  hazardous.
* Lines the console adds (a MODE statement the regime needs, ``server.console.dispatch``) are
  inserted as ordinary, undoable edits and marked in the view (``added_by="console"`` with the
  reason) until they are sent; the operator may delete them like any line. One the operator took
  out is remembered as declined, so the console does not put it back for the same need.
* Selection is a range (click, shift-click, arrows in the page); a refused edit is kept in the
  view (``ProgramView.refusal``, with the statement it concerns) until the next edit or
  selection, so the page shows it on its line. Each statement's planned duration is in the view,
  planned from the start once per change of the program or its start.
* The start: the program plans from ``start_q`` (the model's home, where the statements sent are
  predicted to end, or the robot's reported state after a re-sync); ``start_unknown`` says a
  prediction could not be made (a task, a stop or a failure came first).
"""

from __future__ import annotations

import copy
import json
import logging
from collections.abc import Callable
from pathlib import PurePath
from typing import TYPE_CHECKING

import numpy as np

from server.console.console_lines import ConsoleLines
from server.console.program_plans import ProgramPlans, grip_key
from server.console.task_lines import TaskLines
from server.console.context import ConsoleContext
from server.console.edit_check import rest_breaks
from server.console.enums import Regime
from server.console.errors import ConflictError, ConsoleLineAdded, RefusedByRule
from server.console.events import Notice, ProgramChanged, SessionEvent
from server.console.statement_checks import checked_statement
from server.console.program_entries import EntryViews
from server.console.program_files import LOAD_PHASES, read_program
from server.console.program_start import ProgramStart
from server.console.work import Work
from server.console.views import (
    Caller,
    ProgramView,
    RefusalView,
    StatementView,
    VirtualState,
)
from shared.errors import InputError, TeleprogError
from shared.language.formatter import format_program
from shared.language.parser import parse_statement
from shared.language.statements import Frame, Speed, Statement, Until, program_to_json
from shared.program.editor import KEEP, Editor, ProgramState, Refusal
from shared.program.generator import Generated, JogMode, ProgramGenerator, RobotSample

if TYPE_CHECKING:
    from server.console.control import ControlLock
    from server.console.modes import Modes
    from server.console.ports import PreviewRun, Submitter

log = logging.getLogger(__name__)


def _copy_editor(editor: Editor) -> Editor:
    """An editor with the same state and its own copy of the undo/redo history (the states in
    it are immutable), to try an operation on."""
    trial = copy.copy(editor)
    trial._undo = list(editor._undo)  # noqa: SLF001 - the editor's own lists, copied not changed
    trial._redo = list(editor._redo)  # noqa: SLF001
    return trial


class ProgramDesk(ConsoleLines, ProgramPlans, TaskLines):
    """Editor, generator, files and the program's start."""

    def __init__(self, ctx: ConsoleContext, control: ControlLock, modes: Modes) -> None:
        self._ctx = ctx
        self._control, self._modes = control, modes
        self.preview: PreviewRun | None = None  # set by the session
        self.dispatch: Submitter | None = None  # set by the session
        self._editor = Editor(strict=ctx.settings.strict_editing)
        self._auto = bool(ctx.settings.auto_generate)
        cell = ctx.cell
        self._generator = ProgramGenerator(ctx.settings.generator, world_T_base=cell.world_T_base, world_T_work=cell.frame("work"))
        self._stroke_mode: JogMode | None = None
        self._sample_t = -float("inf")  # time of the last sample fed to the generator
        self._last_generated: tuple[Statement, ProgramState, bool] | None = None
        """The statement generation put last in the program, the editor's state right after, and
        whether undoing the editor's last step takes exactly that statement out (it was inserted)."""
        self.start = ProgramStart(cell.q_home.copy())
        self._confirmed: tuple[int, int, tuple] | None = None
        ConsoleLines.__init__(self)
        self._refusal: tuple[RefusalView, tuple] | None = None  # and the statements it was made on
        ProgramPlans.__init__(self)
        TaskLines.__init__(self)
        self._entries = EntryViews()

    # -- reading -----------------------------------------------------------------------------
    @property
    def state(self) -> ProgramState:
        with self._ctx.lock:
            return self._editor.state

    def view(self) -> ProgramView:
        with self._ctx.lock:
            st = self._editor.state
            durations = self.durations()
            entries = self._entries.views(st.statements, durations, {**self._task_marks(), **self._added_marks()})
            entries.append(StatementView(index=st.empty_index, kind="EMPTY", text="", statement=None))
            e = self._editor
            return ProgramView(
                entries=entries, selected=st.selected_index, selected_range=st.selected_range, refusal=self._shown_refusal(),
                empty_index=st.empty_index, preview=st.preview,
                can_undo=e.can_undo, can_redo=e.can_redo, undo_label=e.undo_label, redo_label=e.redo_label,
                auto_generate=self._auto, start_q=self.start.q.tolist(), start_source=self.start.source,
                confirmed=self.confirmed_range(), strict_editing=e.strict,
            )

    def confirmed_range(self) -> tuple[int, int] | None:
        """The range previewed to its end without warnings, while its statements are unchanged."""
        with self._ctx.lock:
            c = self._confirmed
            if c is None:
                return None
            start, stop, statements = c
            return (start, stop) if tuple(self._editor.state.statements[start:stop]) == statements else None

    def confirm(self, start: int, stop: int) -> None:
        """The range was previewed to its end without warnings (under the lock)."""
        self._confirmed = (start, stop, tuple(self._editor.state.statements[start:stop]))

    def withdraw_confirmation(self) -> None:
        self._confirmed = None

    # -- editing -----------------------------------------------------------------------------
    def set_auto_generate(self, on: bool, *, client: Caller | str | None = None) -> ProgramView:
        """Switch automatic generation; switching on anchors the generator at the arm's state."""
        with self._ctx.lock:
            self._control.check(client)
            flushed = self._generator.finish() if self._auto and not on else []
            self._auto = bool(on)
            self._generator.reset()
            self._stroke_mode = None
        self.take_generated(flushed)
        view = self.view()
        self._ctx.bus.emit([ProgramChanged(program=view)])
        return view

    def select(self, index: int, *, extend: bool = False, client: Caller | str | None = None) -> ProgramView:
        """Select statement ``index`` (0-based; ``empty_index`` is the trailing empty one). Allowed while previewing.
        ``extend``: select the range from the anchor (or the current selection) to ``index`` (a shift-click)."""
        return self._edit(lambda e: e.select(index, extend=extend), client)

    def select_range(self, first: int, last: int, *, client: Caller | str | None = None) -> ProgramView:
        """Select entries ``first..last`` (0-based, both included)."""
        return self._edit(lambda e: e.select_range(first, last), client)

    def move_selection(self, by: int, *, extend: bool = False, client: Caller | str | None = None) -> ProgramView:
        """Move the cursor one entry down (``by=1``) or up (``-1``); ``extend`` keeps the anchor
        (shift+arrow). At either end of the program it stays where it is: an arrow key there is
        harmless, not an error."""
        if by not in (-1, 1):
            raise InputError(f"the selection moves by 1 or -1, not {by}")

        def step(e: Editor) -> object:
            cursor = e.state.selected_index + by
            if not 0 <= cursor <= e.state.empty_index:
                return e.state
            return e.select_next(extend=extend) if by > 0 else e.select_previous(extend=extend)

        return self._edit(step, client)

    def move_statements(self, by: int, *, client: Caller | str | None = None) -> ProgramView:
        """Move the selected statements ``by`` places (negative: up), one undo step; the rest
        re-planned and checked (free editing). A move past either end leaves them where they are."""
        def move(e: Editor) -> object:
            first, last = e.state.selected_range
            stop = min(last, e.state.empty_index - 1)
            if first <= stop and not 0 <= first + by <= stop + by < e.state.empty_index:
                return e.state  # Alt+arrow at the top or the bottom: nothing to do
            return e.move_statements(by)

        return self._edit(move, client, replan=True)

    def set_strict_editing(self, on: bool, *, client: Caller | str | None = None) -> ProgramView:
        """The thesis's editing rules (§4.3.6) on, or free editing (the default); not an edit."""
        def switch(e: Editor) -> object:
            e.strict = bool(on)
            return e.state

        view = self._edit(switch, client)
        log.info("program editing: %s", "strict (thesis §4.3.6)" if on else "free")
        return view

    def insert(self, statement: Statement | str, *, client: Caller | str | None = None) -> ProgramView:
        """Insert a statement (a model, or its text form) before the selection."""
        self._control.check(client)  # before any work on the caller's input
        st = self._statement(statement)
        return self._edit(lambda e: e.insert(st), client, replan=True)

    def delete(self, first: int | None = None, last: int | None = None, *, client: Caller | str | None = None) -> ProgramView:
        """Delete the selected range, or entries ``first..last`` (0-based, both included): one undo step."""
        return self._edit(lambda e: e.delete(first, last), client, replan=True)

    def modify(self, statement: Statement | str, *, client: Caller | str | None = None) -> ProgramView:
        """Replace the selected statement (strict editing: by one of the same kind, §4.3.6)."""
        self._control.check(client)
        st = self._statement(statement)
        return self._edit(lambda e: e.modify(st), client, replan=True)

    def modify_conditions(self, *, speed: Speed | None | object = KEEP, until: Until | None | object = KEEP,
                          client: Caller | str | None = None) -> ProgramView:
        """Set (a value), clear (``None``) or keep (``KEEP``) the WITH speed / UNTIL of the selected action."""
        return self._edit(lambda e: e.modify_conditions(speed, until), client)  # type: ignore[arg-type]

    def undo(self, *, client: Caller | str | None = None) -> ProgramView:
        return self._edit(lambda e: e.undo(), client)

    def redo(self, *, client: Caller | str | None = None) -> ProgramView:
        return self._edit(lambda e: e.redo(), client)

    def load(self, text: str, filename: str = "program.tp", *, client: Caller | str | None = None) -> ProgramView:
        """Replace the program by a file's content (text, or JSON for a .json name); control is
        checked before the costly parse; a broken file is an ``InputError`` at file:line:col. The
        reading runs outside the session's lock (``program_files``), which is taken to check
        control again and put the program, its plan and its lines in place."""
        with self._ctx.lock:
            self._control.check(client)
            start = ProgramStart(self.start.q.copy(), self.start.source, self.start.unknown)
            objects = self.objects_at_start() if self.objects_at_start is not None else None
        name = PurePath(filename).name or "program"
        with Work(self._ctx.bus, self._ctx.clock, "load", f"loading {name}", LOAD_PHASES) as work:
            read = read_program(text, name, self._ctx.cell, None if start.unknown else start.q, work, objects)
            with self._ctx.lock:
                self._control.check(client)
                self.check_not_previewing("load a program")
                self._editor.load(read.state, f"load {name}")  # undo brings back the program it replaced
                self._confirmed = None
                self._console_lines.clear()
                self._declined.clear()
                self._refusal = None
                self._last_generated = None
                self._entries = read.entries
                now = self.start
                if read.planner is not None and np.array_equal(now.q, start.q) and not now.unknown:  # start unmoved
                    # keyed as prefix_planner keys it, so the next change re-plans from where it changed
                    self._planner = (start.q.tobytes() + grip_key(objects), read.planner)
                    self._durations = ((tuple(self._editor.state.statements), start.q.tobytes(), False), read.durations)
                view = self.view()
        n = len(read.state.statements)
        self._ctx.bus.emit([ProgramChanged(program=view), Notice(level="info", message=f"loaded {n} statement(s) from {name}")])
        return view

    def save(self, fmt: str = "text") -> str:
        """The program's file content: ``text`` (the language) or ``json``."""
        with self._ctx.lock:
            statements = list(self._editor.state.statements)
        if fmt == "json":
            return json.dumps(program_to_json(statements), indent=2) + "\n"
        if fmt == "text":
            return format_program(statements)
        raise InputError(f"unknown program format {fmt!r}; valid: text, json")

    def _statement(self, statement: Statement | str) -> Statement:
        """The statement, checked as a program file's would be before it enters the program."""
        if isinstance(statement, str):
            return parse_statement(statement)
        return checked_statement(statement)

    def check_not_previewing(self, what: str) -> None:
        busy = self.preview.running_range()
        if busy is not None:
            raise ConflictError(f"cannot {what} while statements {busy[0] + 1}..{busy[1]} are being previewed; only selection is allowed")

    def _path_not_clear_with(self, editor: Editor, start: int, stop: int) -> dict[int, str]:
        """The previewer's path check (of the desk's program) run on ``editor``'s (under the lock)."""
        kept, self._editor = self._editor, editor
        try:
            return self.preview.path_not_clear(start, stop)
        finally:
            self._editor = kept

    def _edit(self, op: Callable[[Editor], object], client: Caller | str | None, *, replan: bool = False) -> ProgramView:
        """Apply ``op`` to a copy of the editor and keep it when it succeeds; ``replan``: in free
        editing, re-plan the statements after the edit and refuse it where one of them could no
        longer run (``server.console.edit_check``)."""
        with self._ctx.lock:
            self._control.check(client)
            before, shown = self._editor, self._refusal
            trial = _copy_editor(before)
            try:
                result = op(trial)
                refusal = result if isinstance(result, Refusal) else None
                if refusal is None and replan and not trial.strict and self.preview is not None and not self.start.unknown:
                    refusal = rest_breaks(self._path_not_clear_with, before, trial)
                    trial = before if refusal is not None else trial
                self._editor = trial
                self._refusal = None if refusal is None else self._refusal_view(refusal)
                view = self.view()
            except Exception:
                self._editor, self._refusal = before, shown
                raise
        if refusal is not None:
            self._ctx.bus.emit([ProgramChanged(program=view), Notice(level="warning", message=refusal.message, rule=refusal.rule.value)])
            raise RefusedByRule(refusal)
        self._ctx.bus.emit([ProgramChanged(program=view)])
        return view

    def _refusal_view(self, refusal: Refusal) -> tuple[RefusalView, tuple]:
        view = RefusalView(rule=refusal.rule.value, message=refusal.message, index=refusal.index)
        return view, tuple(self._editor.state.statements)

    def _shown_refusal(self) -> RefusalView | None:
        """The last refusal, while the program it was made on is unchanged (under the lock)."""
        if self._refusal is None:
            return None
        view, statements = self._refusal
        return view if statements == tuple(self._editor.state.statements) else None

    def show_refusal(self, refusal: Refusal) -> None:
        """Keep a refusal made elsewhere (a submission's) in the view, on its line, and show it."""
        with self._ctx.lock:
            self._refusal = self._refusal_view(refusal)
        self._ctx.bus.emit([ProgramChanged(program=self.view())])

    # -- the editor, for the other parts (under the lock) ----------------------------------------
    @property
    def editor(self) -> Editor:
        return self._editor

    # -- generation ----------------------------------------------------------------------------
    def sample_stroke(self, before: VirtualState, after: VirtualState, mode: JogMode, frame: str | None = None) -> list[Generated]:
        """Feed one change of the virtual arm to the generator (under the lock); what it made.
        ``frame``: the jog frame of a tool motion, the frame its statements are written in."""
        if not self._auto:
            return []
        generated: list[Generated] = []
        # samples must come in increasing time: changes within one clock tick (a fast caller, a
        # test's manual clock) are spaced a microsecond apart
        last = self._sample_t
        now = max(self._ctx.clock(), last + 2e-6)
        if mode is JogMode.TOOL and frame is not None:
            generated += self._generator.set_frame(GENERATED_FRAME.get(frame, self._ctx.settings.generator.frame))
        if self._stroke_mode is not None and self._stroke_mode is not mode:
            generated += self._generator.finish()
        if self._stroke_mode is not mode:
            # a fresh stroke: the state before it is the stroke's first sample
            first = max(now - 1e-3, (last + now) / 2.0)
            generated += self._generator.push(RobotSample(t=first, q=before.q.copy(), mode=mode, world_T_tool=before.world_T_tcp))
            self._stroke_mode = mode
        generated += self._generator.push(RobotSample(t=now, q=after.q.copy(), mode=mode, world_T_tool=after.world_T_tcp))
        self._sample_t = now
        return generated

    def end_stroke(self, *, client: Caller | str | None = None) -> ProgramView:
        """The operator let go: close the open generated segment."""
        with self._ctx.lock:
            self._control.check(client)
            statements = self._generator.finish() if self._auto else []
            self._stroke_mode = None  # the next stroke starts with the state it starts from
        self.take_generated(statements)
        return self.view()

    def reset_generator(self) -> None:
        """Anchor generation afresh (a re-sync; under the lock)."""
        self._generator.reset()
        self._stroke_mode = None
        self._last_generated = None

    def take_generated(self, statements: list[Generated]) -> None:
        """Put generated statements at the program's end, a continuing one in place of the last
        generated statement; in the free regime stream them."""
        if not statements:
            return
        notices: list[SessionEvent] = []
        with self._ctx.lock:
            editor = self._editor
            keep = editor.state.selected_index
            at_end = keep == editor.state.empty_index
            inserted = 0
            for g in statements:
                st = g.statement
                if editor.state.previewing:
                    break
                if g.continues and self._replace_last_generated(editor, st):
                    inserted += 1
                    continue
                editor.select_empty()
                result = editor.insert(st)
                if isinstance(result, Refusal):
                    notices.append(Notice(level="warning", message=f"generated {st.kind} not added: {result.message}", rule=result.rule.value))
                    break
                self._last_generated = (st, editor.state, True)
                inserted += 1
            if not at_end and keep < editor.state.empty_index:
                editor.select(keep)
            if self._last_generated is not None and inserted:
                self._last_generated = (self._last_generated[0], editor.state, self._last_generated[2])
            stream = inserted and self._modes.regime is Regime.FREE and self.dispatch.connected
        self._ctx.bus.emit([ProgramChanged(program=self.view()), *notices])
        if stream:
            hazard = self.preview.hazard()
            if hazard is not None:
                self._ctx.bus.emit([Notice(level="warning", message=(
                    f"held back, not sent to the robot: {hazard}; the program keeps it (undo, edit or delete it)"))])
                return
            try:
                try:
                    self.dispatch.submit(0, self.state.empty_index, client=self._control.holder)
                except ConsoleLineAdded:  # the line is in the program, shown: stream it with the rest
                    self.dispatch.submit(0, self.state.empty_index, client=self._control.holder)
            except TeleprogError as exc:
                self._ctx.bus.emit([Notice(level="warning", message=f"streaming refused: {exc}")])

    def _replace_last_generated(self, editor: Editor, statement: Statement) -> bool:
        """Put ``statement`` in place of the last generated statement while that is still the
        program's last statement, unchanged (not sent, edited or deleted); under the lock.
        Untouched since it was added, its insertion is undone and ``statement`` inserted: one
        edit for the stroke. Otherwise the last statement is modified (an edit of its own)."""
        last = self._last_generated
        statements = editor.state.statements
        if last is None or not statements or statements[-1] != last[0]:
            return False
        if editor.state is last[1] and last[2] and editor.can_undo:
            editor.undo()
            editor.select_empty()
            if not isinstance(editor.insert(statement), Refusal):
                self._last_generated = (statement, editor.state, True)
                return True
            editor.redo()
            return False
        editor.select(len(statements) - 1)
        if isinstance(editor.modify(statement), Refusal):
            return False
        self._last_generated = (statement, editor.state, False)
        return True


#: the jog frames whose names are statement frames; a tool-frame jog writes in the default frame
GENERATED_FRAME = {"world": Frame.WORLD, "base": Frame.BASE, "work": Frame.WORK}
