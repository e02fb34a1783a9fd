"""The submit-and-monitor panel (thesis 4.3.6, 4.4): submit a range of the program, then follow
each sent statement by its robot number and status (received, running, done, failed) with its
timing. STOP and recovery live in the header (webui.stop_header) so they stay in view on every tab.
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

SHOWN = 14  # the newest sent statements listed; older ones stay in the API


def sent_line(item: SentView, now: float) -> str:
    number = f"#{item.number}" if item.number is not None else "#?"
    timing = ""
    if item.run_s is not None:
        timing = f", ran {item.run_s:.1f} s"
    elif item.started_at is not None and item.status is SentStatus.RUNNING:
        timing = f", running {now - item.started_at:.1f} s"
    elif item.status not in FINAL_SENT:
        timing = f", sent {now - item.submitted_at:.1f} s ago"
    reason = f": {item.reason}" if item.reason else ""
    return f"{number} `{item.text}`: {STATUS_MARK[item.status]}{timing}{reason}"


def sent_markdown(view: SentListView, now: float | None = None) -> str:
    now = time.time() if now is None else now
    if not view.items:
        return "Nothing sent yet."
    items = view.items[-SHOWN:]
    lines = [f"{len(view.items)} sent, {view.pending} pending"]
    if len(view.items) > SHOWN:
        lines.append(f"(oldest {len(view.items) - SHOWN} not shown)")
    lines += [sent_line(item, now) for item in items]
    return "  \n".join(lines)


class MonitorPanel:
    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions) -> None:
        self.server = server
        self.session = session
        self.actions = actions
        gui = server.gui
        self.range = StatementRange(gui, "Submit from", "Submit to")
        self.needs = SubmitNeeds(gui, session, actions, self.range)  # what Submit needs, before the click
        self.submit = gui.add_button("Submit range", color="green", icon=viser.Icon.SEND)
        self.submit.on_click(self._on_submit)
        self.needs.add_button(gui)
        self.sent = gui.add_markdown("Nothing sent yet.")
        self._view: SentListView | None = None

    def _on_submit(self, _event: viser.GuiEvent) -> None:
        start, stop = self.range.slice(release=True)  # the program shrinks: next, all that is left
        self.actions.run("submit", lambda: self.session.dispatch.submit(start, stop))

    def show_program(self, view: ProgramView) -> None:
        self.range.follow(view)
        self.needs.refresh()

    def show(self, view: SentListView) -> None:
        self._view = view
        self.sent.content = sent_markdown(view, self.session.wall_clock())

    def tick(self) -> None:
        """Refresh the running times while something is not final (called with link updates)."""
        view = self._view
        if view is not None and view.pending:
            self.sent.content = sent_markdown(view, self.session.wall_clock())
