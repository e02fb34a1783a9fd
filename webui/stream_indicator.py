"""On the Drive tab, while the operator drags the tool: whether this drag runs on the robot
(ONLINE: generated statements stream to it as they are made) or only moves the virtual arm, and
how many statements the drag has sent so far (thesis §4.2.1: in the free zone the virtual and the
real robot move master-slave, so the operator must see that a drag is not a rehearsal).

It watches the gizmo's drag phases (a callback of its own beside the driving panel's) and shows
the session's views: ``SubmitReadiness.streams`` says whether generated statements stream now,
the sent list's length counts what went. ``data-streaming`` carries the state for tests.
"""

from __future__ import annotations

import html
import threading

import viser

from server.console import SentListView, SubmitReadiness

ONLINE = "#0b7285"


def indicator_html(dragging: bool, streams: bool, sent: int, last: int | None) -> str:
    """``sent``: statements sent since the drag began; ``last``: sent by the last streaming drag
    (its final segment goes when the operator lets go), None when it did not stream."""
    if dragging and streams:
        text = f"ONLINE: this drag runs on the robot as you drive ({sent} statement(s) sent so far)"
        return (f'<div data-streaming="true" style="background:{ONLINE};color:#fff;padding:3px 8px;border-radius:4px;'
                f'font-weight:600">&#9679; {html.escape(text)}</div>')
    if dragging:
        return '<div data-streaming="false">This drag moves the virtual arm only; nothing goes to the robot until you send it</div>'
    if last:
        return f'<div data-streaming="false">Last drag sent {last} statement(s) to the robot</div>'
    return '<div data-streaming="false"></div>'


class StreamIndicator:
    """The line under the driving controls (see the module docstring)."""

    def __init__(self, gui: viser.GuiApi) -> None:
        self._lock = threading.Lock()
        self._dragging = False
        self._streams = False
        self._sent_total = 0
        self._at_start = 0
        self._last_streamed = False
        self.html = gui.add_html(indicator_html(False, False, 0, None))

    def watch(self, gizmo) -> None:
        gizmo.on_update(self._on_gizmo)

    def _on_gizmo(self, event) -> None:
        phase = getattr(event, "phase", "update")
        with self._lock:
            if phase == "start":
                self._dragging, self._at_start, self._last_streamed = True, self._sent_total, self._streams
            elif phase == "end":
                self._dragging = False
            else:
                return
            self._draw()

    # -- session events -----------------------------------------------------------------------
    def show_readiness(self, view: SubmitReadiness) -> None:
        with self._lock:
            self._streams = view.streams
            if self._dragging:
                self._last_streamed = self._last_streamed or view.streams
            self._draw()

    def show_sent(self, view: SentListView) -> None:
        with self._lock:
            self._sent_total = len(view.items)
            self._draw()

    def _draw(self) -> None:
        sent = self._sent_total - self._at_start
        content = indicator_html(self._dragging, self._streams, sent, sent if self._last_streamed else None)
        if self.html.content != content:
            self.html.content = content
