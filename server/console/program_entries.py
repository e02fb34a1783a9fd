"""The program's lines as views, made once each: a change costs what it changes.

``ProgramDesk.view`` runs after every edit and every generated statement. Formatting every
statement and building its view each time made a generated statement cost in proportion to
the program (about 100 ms a view at 1,000 statements, most of it ``format_statement``). Here a
line's text is kept per statement object (statements are immutable: the editor keeps the same
object for a line that did not change, wherever it moves), and the views of the last call are
kept: the lines before the first change (found by comparing slices in C,
``shared.motion.prefix_planner.common_prefix``) are the same views, and only the lines from there
on are looked at, each made anew only when its statement, duration or console mark changed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from server.console.views import StatementView
from shared.language.formatter import format_statement
from shared.language.statements import Statement
from shared.motion.prefix_planner import common_prefix

_NONE: dict = {}


class EntryViews:
    """The cache of line texts and line views (used under the session's lock)."""

    def __init__(self) -> None:
        self._texts: dict[int, tuple[Statement, str]] = {}  # id(statement) -> (statement kept alive, text)
        self._views: list[tuple[Statement, float | None, dict, StatementView] | None] = []
        self._last: tuple[tuple[Statement, ...], list[float | None], dict[int, dict], list[StatementView]] | None = None

    def text(self, statement: Statement) -> str:
        kept = self._texts.get(id(statement))
        if kept is not None and kept[0] is statement:
            return kept[1]
        text = format_statement(statement)
        self._texts[id(statement)] = (statement, text)
        return text

    def views(self, statements: Sequence[Statement], durations: Sequence[float | None],
              marked: Mapping[int, dict]) -> list[StatementView]:
        """One view per statement, index by index (a new list); ``marked``: the console marks of
        statements, by ``id``. Only lines from the first change on are looked at."""
        statements, durations, marked = tuple(statements), list(durations), dict(marked)
        n = len(statements)
        if len(durations) != n:
            raise ValueError(f"{n} statements but {len(durations)} durations")
        first = 0
        if self._last is not None and self._last[2] == marked:
            old_statements, old_durations, _, old_out = self._last
            first = min(common_prefix(old_statements, statements), common_prefix(old_durations, durations))
            out = old_out[:first]
        else:
            out = []
        del self._views[n:]
        self._views.extend([None] * (n - len(self._views)))
        for i in range(first, n):
            s, d = statements[i], durations[i]
            marks = marked.get(id(s), _NONE)
            kept = self._views[i]
            if kept is None or kept[0] is not s or kept[1] != d or kept[2] != marks:
                view = StatementView(index=i, kind=s.kind, text=self.text(s), statement=s, duration_s=d, **marks)
                kept = self._views[i] = (s, d, marks, view)
            out.append(kept[3])
        self._last = (statements, durations, marked, out)
        if len(self._texts) > 2 * n + 64:  # statements long gone: keep only the program's
            alive = {id(s) for s in statements}
            self._texts = {k: v for k, v in self._texts.items() if k in alive}
        return list(out)
