"""A range of program statements typed as two numbers (from, to; counted from 1 as the
operator counts), as the Preview and Submit tabs both ask for one.

Until the operator touches them the numbers follow the program: the lines selected in the
program list when they are more than one statement, else every real statement. Once touched they
are kept (clipped to the program) until the range has been used. Any range can be typed; what may
be done with it is the editor's to say (a refusal names its rule on the line it concerns).
"""

from __future__ import annotations

import viser

from server.console import ProgramView


def followed_range(view: ProgramView) -> tuple[int, int]:
    """The range an untouched pair of boxes shows, counted from 1: the selected statements when
    the selection spans more than one real statement, else all of them."""
    n = max(1, view.empty_index)
    if view.selected_range is not None:
        first, last = view.selected_range
        last = min(last, view.empty_index - 1)
        if first < last:
            return first + 1, last + 1
    return 1, n


class StatementRange:
    def __init__(self, gui: viser.GuiApi, first_label: str, last_label: str,
                 first_hint: str | None = None, last_hint: str | None = None) -> None:
        self.first = gui.add_number(first_label, 1, min=1, step=1, hint=first_hint)
        self.last = gui.add_number(last_label, 1, min=1, step=1, hint=last_hint)
        self._touched = False
        self.first.on_update(self._on_touch)
        self.last.on_update(self._on_touch)

    def _on_touch(self, event: viser.GuiEvent) -> None:
        if event.client is not None:  # the operator, not our own update
            self._touched = True

    def slice(self, *, release: bool = False) -> tuple[int, int]:
        """The range as list indices ``start, stop`` (stop exclusive); ``release``: the next
        program change resets it to follow the program (it was used up, e.g. submitted)."""
        if release:
            self._touched = False
        return int(self.first.value) - 1, int(self.last.value)

    def follow(self, view: ProgramView) -> None:
        """Keep the range inside the program; untouched, it follows the program (``followed_range``)."""
        n = max(1, view.empty_index)
        self.first.max = n
        self.last.max = n
        if not self._touched:
            self.first.value, self.last.value = followed_range(view)
        elif self.last.value > n:
            self.first.value = min(int(self.first.value), n)
            self.last.value = n
