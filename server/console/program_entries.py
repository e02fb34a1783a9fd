"""The program's lines as views, made once each: a change costs what it changes.

``ProgramDesk.view`` runs after every edit and every generated statement. Formatting every
statement and building its view each time made a generated statement cost in proportion to
the program (about 100 ms a view at 1,000 statements, most of it ``format_statement``). Here a
line's text is kept per statement object (statements are immutable: the editor keeps the same
object for a line that did not change, wherever it moves), and a line's view per place while
its statement, duration and console mark stay the same.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from server.console.views import StatementView
from shared.language.formatter import format_statement
from shared.language.statements import Statement


class EntryViews:
    """The cache of line texts and line views (used under the session's lock)."""

    def __init__(self) -> None:
        self._texts: dict[int, tuple[Statement, str]] = {}  # id(statement) -> (statement kept alive, text)
        self._views: list[tuple[Statement, float | None, dict, StatementView] | None] = []

    def text(self, statement: Statement) -> str:
        kept = self._texts.get(id(statement))
        if kept is not None and kept[0] is statement:
            return kept[1]
        text = format_statement(statement)
        self._texts[id(statement)] = (statement, text)
        return text

    def views(self, statements: Sequence[Statement], durations: Sequence[float | None],
              added: Callable[[Statement], dict]) -> list[StatementView]:
        """One view per statement, index by index; only lines that changed are made anew."""
        n = len(statements)
        del self._views[n:]
        self._views.extend([None] * (n - len(self._views)))
        out = []
        for i, (s, d) in enumerate(zip(statements, durations, strict=True)):
            marks = added(s)
            kept = self._views[i]
            if kept is None or kept[0] is not s or kept[1] != d or kept[2] != marks:
                view = StatementView(index=i, kind=s.kind, text=self.text(s), statement=s, duration_s=d, **marks)
                kept = self._views[i] = (s, d, marks, view)
            out.append(kept[3])
        if len(self._texts) > 2 * n + 64:  # statements long gone: keep only the program's
            alive = {id(s) for s in statements}
            self._texts = {k: v for k, v in self._texts.items() if k in alive}
        return out
