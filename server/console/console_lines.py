"""The lines the console puts into the program (``server.console.dispatch``: a MODE statement the
regime needs): marked in the view until they are sent, and remembered as declined once the
operator takes one out, so the console does not put it back for the same need.

A part of :class:`server.console.program_desk.ProgramDesk`, kept in a room of its own; its methods
run under the session's lock and use the desk's editor and confirmed range.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from server.console.enums import Regime
from server.console.errors import RefusedByRule
from shared.language.formatter import format_statement
from shared.language.statements import Statement
from shared.program.editor import Editor, Refusal

log = logging.getLogger(__name__)


@dataclass
class ConsoleLine:
    """A line the console put into the program: the statement itself (compared by identity, so an
    equal line the operator typed is the operator's) and why."""

    statement: Statement
    reason: str
    regime: Regime  # the regime whose need it was


class ConsoleLines:
    """The desk's console lines (a mixin: the desk holds ``_editor`` and ``_confirmed``)."""

    _editor: Editor
    _confirmed: tuple[int, int, tuple] | None

    def __init__(self) -> None:
        self._console_lines: list[ConsoleLine] = []  # added by the console, not sent yet
        self._declined: list[ConsoleLine] = []  # console lines the operator took out

    def _added_marks(self) -> dict[int, dict]:
        """The view fields of the lines the console added, by ``id`` of their statement."""
        return {id(c.statement): {"added_by": "console", "added_reason": c.reason} for c in self._console_lines}

    def _note_removed(self) -> None:
        """Console lines no longer in the program were taken out by the operator (sent ones are
        dropped by :meth:`lines_sent` first): they are declined."""
        present = self._editor.state.statements
        for line in list(self._console_lines):
            if not any(s is line.statement for s in present):
                self._console_lines.remove(line)
                self._declined.append(line)

    def declined(self, statement: Statement, regime: Regime) -> bool:
        """Whether the operator took out a console line equal to ``statement`` that the console
        added for ``regime`` (:meth:`forget_declined` clears that when the robot's mode changes)."""
        self._note_removed()
        return any(d.statement == statement and d.regime is regime for d in self._declined)

    def forget_declined(self) -> None:
        self._declined.clear()

    def add_console_line(self, index: int, statement: Statement, reason: str, regime: Regime) -> int:
        """Insert ``statement`` before program index ``index`` as a line added by the console (an
        undoable edit, the selection kept on its statement); returns its line number (from 1).

        Only parameter statements are added, which change no path: a confirmed preview whose
        range the line joins at its start or inside stays confirmed, grown by the line."""
        self._note_removed()
        editor = self._editor
        keep = editor.state.selected_statement
        for result in (editor.select(index), editor.insert(statement)):
            if isinstance(result, Refusal):
                raise RefusedByRule(result)
        state = editor.state
        editor.select(next((i for i, s in enumerate(state.entries) if s is keep), state.empty_index))
        self._console_lines.append(ConsoleLine(statement, reason, regime))
        c = self._confirmed
        if c is not None and c[0] <= index < c[1] and tuple(state.statements[c[0]:c[1] + 1]) == (
            *c[2][: index - c[0]], statement, *c[2][index - c[0]:]
        ):
            self._confirmed = (c[0], c[1] + 1, tuple(state.statements[c[0]:c[1] + 1]))
        log.info("console added line %d: %s (%s)", index + 1, format_statement(statement), reason)
        return index + 1

    def lines_sent(self, statements: list[Statement]) -> None:
        """These statements left the program for the robot: they are no longer console lines."""
        self._console_lines = [c for c in self._console_lines if not any(c.statement is s for s in statements)]
