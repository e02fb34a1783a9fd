"""A range of program statements typed as two numbers (from, to; counted from 1 as the
operator counts), as the Preview and Submit tabs both ask for one.

Until the operator touches them the numbers follow the program and cover every real statement;
once touched they are kept (clipped to the program) until the range has been used.
"""

from __future__ import annotations

import viser

from server.console import ProgramView


class StatementRange:
    def __init__(self, gui: viser.GuiApi, first_label: str, last_label: str) -> None:
        self.first = gui.add_number(first_label, 1, min=1, step=1)
        self.last = gui.add_number(last_label, 1, min=1, step=1)
        self._touched = False
        self.first.on_update(self._on_touch)
        self.last.on_update(self._on_touch)

    def _on_touch(self, event: viser.GuiEvent) -> None:
        if event.client is not None:  # the operator, not our own update
            self._touched = True

    def slice(self, *, release: bool = False) -> tuple[int, int]:
        """The range as list indices ``start, stop`` (stop exclusive); ``release``: the next
        program change resets it to the whole program (it was used up, e.g. submitted)."""
        if release:
            self._touched = False
        return int(self.first.value) - 1, int(self.last.value)

    def follow(self, view: ProgramView) -> None:
        """Keep the range inside the program; untouched, it covers every real statement."""
        n = max(1, view.empty_index)
        self.first.max = n
        self.last.max = n
        if not self._touched or self.last.value > n:
            self.first.value = min(int(self.first.value), n) if self._touched else 1
            self.last.value = n
