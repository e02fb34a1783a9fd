"""Lines a task-level command puts into the program (issue 40: ``POST /api/task/goal``,
``POST /api/task/action``, the Task tab's buttons): the statements of each action, inserted
before the selection as one edit (one undo step takes the whole plan out), each checked as an
insertion by hand is, and marked in the program view with the action it serves. They are
ordinary lines otherwise: previewed, edited and submitted as any other.

A part of :class:`server.console.program_desk.ProgramDesk` in a room of its own; it uses the
desk's editor, control check and edit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from server.console.context import ConsoleContext
from server.console.control import ControlLock
from server.console.views import Caller, ProgramView
from shared.language.statements import Statement
from shared.program.editor import Editor, Refusal


class TaskLines:
    """The desk's task lines: ``id`` of the statement -> (the statement kept alive, its action)."""

    _ctx: ConsoleContext
    _control: ControlLock
    _editor: Editor
    _statement: Callable[[Statement | str], Statement]
    _edit: Callable[..., ProgramView]

    def __init__(self) -> None:
        self._task_lines: dict[int, tuple[Statement, str]] = {}

    def insert_actions(self, rows: Sequence[tuple[str, Sequence[Statement | str]]], label: str, *,
                       client: Caller | str | None = None) -> ProgramView:
        """Insert each action's statements (``rows``: the action's text and its statements, in
        order) before the selection, as one edit named ``label``; a statement the editor refuses
        refuses the whole edit (nothing is inserted), as one typed by hand would be refused."""
        self._control.check(client)  # before any work on the caller's input
        lines = [(action, self._statement(s)) for action, statements in rows for s in statements]

        def insert_all(editor: Editor) -> object:
            state = editor.state
            for _, statement in lines:
                result = state.insert(statement, strict=editor.strict)
                if isinstance(result, Refusal):
                    return result
                state = result
            return editor.load(state, label)

        with self._ctx.lock:  # marked first, so the edit's own view and event show the actions
            self._forget_gone_task_lines()
            for action, statement in lines:
                self._task_lines[id(statement)] = (statement, action)
            try:
                return self._edit(insert_all, client, replan=True)
            except Exception:
                for _, statement in lines:
                    self._task_lines.pop(id(statement), None)
                raise

    def planned_actions(self) -> list[str]:
        """The actions the program's task lines serve, in program order (each run of lines once)."""
        with self._ctx.lock:
            out: list[str] = []
            for statement in self._editor.state.statements:
                kept = self._task_lines.get(id(statement))
                if kept is not None and kept[0] is statement and (not out or out[-1] != kept[1]):
                    out.append(kept[1])
            return out

    def _task_marks(self) -> dict[int, dict]:
        """The program view's fields of the task lines, by ``id`` of their statement."""
        return {key: {"action": action} for key, (_, action) in self._task_lines.items()}

    def _forget_gone_task_lines(self) -> None:
        """Task lines no longer in the program (deleted, sent) are forgotten once they outnumber it."""
        present = self._editor.state.statements
        if len(self._task_lines) > 2 * len(present) + 64:
            alive = {id(s) for s in present}
            self._task_lines = {k: v for k, v in self._task_lines.items() if k in alive}
