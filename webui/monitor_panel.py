"""The submit-and-monitor panel (thesis 4.3.6, 4.4): submit a range of the program, then follow
each sent statement by its robot number and status (received, running, done, failed) with its
timing. STOP and recovery live in the header (webui.stop_header) so they stay in view on every tab.

The sent list pages: the newest ``SHOWN`` statements first (page 1), Older / Newer reach the rest,
and the list says which page of how many it shows.
"""

from __future__ import annotations

import time

import viser

from server.console import (
    FINAL_SENT,
    ProgramView,
    SentListView,
    SentStatus,
    SentView,
    Session,
)
from webui.actions import Actions
from webui.statement_range import StatementRange
from webui.submit_needs import SubmitNeeds

STATUS_MARK = {
    SentStatus.SENDING: "sending",
    SentStatus.RECEIVED: "received",
    SentStatus.RUNNING: "**running**",
    SentStatus.DONE: "done",
    SentStatus.FAILED: "**FAILED**",
    SentStatus.SKIPPED: "skipped",
    SentStatus.ABORTED: "aborted",
    SentStatus.REJECTED: "**REJECTED**",
    SentStatus.UNKNOWN: "**UNKNOWN**",
}

SHOWN = 14  # sent statements on one page of the list; page 1 holds the newest


def sent_line(item: SentView, now: float) -> str:
    number = f"#{item.number}" if item.number is not None else "#?"
    timing = ""
    if item.run_s is not None:
        timing = f", ran {item.run_s:.1f} s"
    elif item.started_at is not None and item.status is SentStatus.RUNNING:
        timing = f", running {now - item.started_at:.1f} s"
    elif item.status not in FINAL_SENT:
        timing = f", sent {now - item.submitted_at:.1f} s ago"
    if item.before:  # the robot's account when this console connected: held means Resume runs it
        mark = "**held**" if item.status is SentStatus.RECEIVED else STATUS_MARK[item.status]
        return f"{number} `{item.text}`: {mark}{timing} (sent before this console started)"
    reason = f": {item.reason}" if item.reason else ""
    return f"{number} `{item.text}`: {STATUS_MARK[item.status]}{timing}{reason}"


def page_count(total: int, size: int = SHOWN) -> int:
    """How many pages ``total`` sent statements fill (at least one)."""
    return max(1, -(-total // size))


def page_slice(total: int, page: int, size: int = SHOWN) -> tuple[int, int, int]:
    """``(page, start, stop)``: the page clipped to those there are (0 is the newest) and the
    slice of the sent list it shows, oldest first."""
    page = min(max(page, 0), page_count(total, size) - 1)
    stop = total - page * size
    return page, max(0, stop - size), stop


def sent_markdown(view: SentListView, now: float | None = None, page: int = 0) -> str:
    """One page of the sent list (0: the newest statements), newest first: what runs now and
    what waits behind it stay at the top, never below the fold."""
    now = time.time() if now is None else now
    if not view.items:
        return "Nothing sent yet."
    total = len(view.items)
    page, start, stop = page_slice(total, page)
    lines = [f"{total} sent, {view.pending} pending"]
    pages = page_count(total)
    if pages > 1:
        which = " (newest)" if page == 0 else " (oldest)" if page == pages - 1 else ""
        lines.append(f"Page {page + 1} of {pages}{which}: sent {start + 1}-{stop} of {total}")
    lines += [sent_line(item, now) for item in reversed(view.items[start:stop])]
    return "  \n".join(lines)


class MonitorPanel:
    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions) -> None:
        self.server = server
        self.session = session
        self.actions = actions
        gui = server.gui
        self.range = StatementRange(
            gui, "Submit from", "Submit to",
            first_hint="any statement may be typed; the editor sends a range that starts at statement 1 "
            "(the robot continues from where it already is) and says on the line why another cannot go",
        )
        self.needs = SubmitNeeds(gui, session, actions, self.range)  # what Submit needs, before the click
        self.submit = gui.add_button("Submit range", color="green", icon=viser.Icon.SEND)
        self.submit.on_click(self._on_submit)
        self.needs.add_button(gui)
        self.pages = gui.add_button_group("Sent list", ("Older", "Newer"))
        self.pages.on_click(self._on_page)
        self.sent = gui.add_markdown("Nothing sent yet.")
        self._view: SentListView | None = None
        self._page = 0  # 0: the newest statements

    def _on_page(self, event: viser.GuiEvent) -> None:
        """Older / Newer: which page of the sent list is shown (display only)."""
        total = len(self._view.items) if self._view is not None else 0
        step = 1 if event.target.value == "Older" else -1
        self._page, _, _ = page_slice(total, self._page + step)
        self._draw()

    def _draw(self) -> None:
        if self._view is not None:
            self.sent.content = sent_markdown(self._view, self.session.wall_clock(), self._page)

    def _on_submit(self, _event: viser.GuiEvent) -> None:
        start, stop = self.range.slice(release=True)  # the program shrinks: next, all that is left
        self.actions.run("submit", lambda: self.session.dispatch.submit(start, stop))

    def show_program(self, view: ProgramView) -> None:
        self.range.follow(view)
        self.needs.refresh()
        empty = view.empty_index == 0  # nothing to submit: the buttons say so by being off
        for button in (self.submit, self.needs.button):
            if button is not None and button.disabled != empty:
                button.disabled = empty

    def show(self, view: SentListView) -> None:
        self._view = view
        self._draw()

    def tick(self) -> None:
        """Refresh the running times while something is not final (called with link updates)."""
        view = self._view
        if view is not None and view.pending:
            self._draw()
