"""What Submit needs, shown on the Submit tab before the click (thesis §4.2.1: each regime sends
its own way), and the "Preview and submit" button that meets the OFFLINE regime's need in one
click.

The line is the session's ``SubmitReadiness`` for the tab's range: the session publishes it for
the whole program (``ReadinessChanged``); when the operator typed another range the line asks the
session for that one. Its words come from the same checks Submit applies, so what the line says
and what a click gets cannot disagree. ``data-submit-ready`` carries the answer for tests.
"""

from __future__ import annotations

import html
import logging

import viser

from server.console import PreviewView, Session, SubmitReadiness
from webui.actions import Actions
from webui.statement_range import StatementRange

log = logging.getLogger(__name__)

READY, WAITING = "#2b8a3e", "#495057"


def speed_words(speed: float | str) -> str:
    return "instantly (checked at once)" if speed == "instant" else f"at {float(speed):g}x"


def needs_html(view: SubmitReadiness | None, speed: float | str = 1.0) -> str:
    if view is None:
        return '<div data-submit-ready="">Submit: -</div>'
    colour = READY if view.ready else WAITING
    after = f"Preview and submit plays the range {speed_words(speed)} (Preview tab: Preview speed), then sends it if it ends without warnings"
    return (f'<div data-submit-ready="{str(view.ready).lower()}" data-regime="{view.regime.value}" '
            f'style="border-left:4px solid {colour};padding:2px 6px;margin:2px 0">'
            f"{html.escape(view.line)}"
            f'<div style="font-size:0.85em;color:#868e96">{html.escape(after)}</div></div>')


class SubmitNeeds:
    """The line above the Submit button, and the "Preview and submit" button under it."""

    def __init__(self, gui: viser.GuiApi, session: Session, actions: Actions, statement_range: StatementRange) -> None:
        self.session = session
        self.actions = actions
        self.range = statement_range
        self._whole: SubmitReadiness | None = None
        self._speed: float | str = 1.0
        self.line = gui.add_html(needs_html(None))
        statement_range.first.on_update(lambda _: self.refresh())
        statement_range.last.on_update(lambda _: self.refresh())
        self.button: viser.GuiButtonHandle | None = None

    def add_button(self, gui: viser.GuiApi) -> viser.GuiButtonHandle:
        """The "Preview and submit" button (placed by the panel, under its Submit button)."""
        self.button = gui.add_button(
            "Preview and submit", color="indigo", icon=viser.Icon.PLAYER_PLAY,
            hint="preview the range at the preview speed; if it ends without warnings, send it",
        )
        self.button.on_click(self._on_click)
        return self.button

    def _on_click(self, _event: viser.GuiEvent) -> None:
        start, stop = self.range.slice(release=True)
        self.actions.run("preview and submit", lambda: self.session.preview.preview_and_submit(start, stop))

    # -- session events -----------------------------------------------------------------------
    def show(self, view: SubmitReadiness) -> None:
        self._whole = view
        self.refresh()

    def show_preview(self, view: PreviewView) -> None:
        if view.speed != self._speed:
            self._speed = view.speed
            self.refresh()

    def refresh(self) -> None:
        """Draw the line for the tab's range: the published answer when it is the whole program,
        else the session's answer for that range (a read)."""
        view = self._whole
        if view is None:
            return
        start, stop = self.range.slice()
        if (start, stop) != (view.start, view.stop) and view.stop > 0:
            try:
                view = self.session.readiness.view(start, stop)
            except Exception:  # noqa: BLE001 - a line must show, never break the panel
                log.exception("readiness of %d..%d", start, stop)
        content = needs_html(view, self._speed)
        if self.line.content != content:
            self.line.content = content
