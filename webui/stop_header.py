"""The console's header: STOP, the robot's state and what became of the last STOP, in a panel of
its own docked above the control panel, so it never scrolls away with the program (viser has no
fixed header; a standalone panel is its own scroll region).

Pressing STOP shows at once "STOP sent, arrives in about N s" (N: the link's measured one-way
delay), and the robot's confirmation when its answer is back; that line stands while the robot
holds after it (stopped, at fault) and goes once it leaves that hold (resumed, skipped, aborted). The state line is coloured: red
for a fault or a lost link, amber for stopped. After a contact fault it offers "Back away".
"""

from __future__ import annotations

import html
import logging
import time
from collections.abc import Callable

import viser

from server.console import LinkView, Notice, Session
from webui.actions import Actions

log = logging.getLogger(__name__)

RED, AMBER, GREEN, GREY = "#c92a2a", "#e67700", "#2b8a3e", "#495057"
STATE_LOOK = {
    "fault": (RED, "FAULT: stopped on something unexpected; resume, skip, abort or back away"),
    "stopped": (AMBER, "STOPPED: holding; resume, skip or abort"),
    "disconnected": (RED, "DISCONNECTED from the console: it starts nothing new"),
    "running": (GREEN, "running"),
    "idle": (GREY, "idle"),
}


def state_html(link: LinkView | None) -> str:
    """The robot's state as a coloured bar (the text says it too, for readers without colour)."""
    if link is None or not link.configured:
        colour, text = GREY, "Robot: none configured (console alone)"
    elif not link.connected:
        colour, text = RED, "Robot: link NOT CONNECTED"
    elif link.robot_state is None:
        colour, text = GREY, "Robot: no telemetry yet"
    else:
        colour, words = STATE_LOOK.get(link.robot_state, (GREY, link.robot_state))
        text = f"Robot {words}"
    return (f'<div data-robot-state="{html.escape(link.robot_state or "") if link else ""}" '
            f'style="background:{colour};color:#fff;padding:3px 8px;border-radius:4px;font-weight:600">'
            f"{html.escape(text)}</div>")


def stop_sent_text(link: LinkView | None) -> str:
    """What the operator reads the moment STOP leaves the console."""
    if link is None or not link.connected:
        return "**STOP sent**: the link is down, it goes out when the link is back"
    if link.delay_s is None:
        return "**STOP sent**: arrives after the link's delay (not measured yet)"
    return f"**STOP sent**, arrives in about {link.delay_s:.1f} s"


def stop_answer_text(answer: str, took_s: float, link: LinkView) -> str:
    """What the operator reads when the robot's answer to STOP is back (``answer``: the
    session's notice about it, '' if none came). The robot's own words in its acknowledgement
    say what it did; telemetry travels on another channel and may not show the stop yet."""
    state = f"robot {link.robot_state}" if link.robot_state else "robot state unknown"
    applied = "robot applied stop: "
    if answer.startswith(applied):
        state = f"robot {answer.removeprefix(applied)}"
    if answer.startswith("stop failed"):
        return f"**STOP not confirmed**: {answer}"
    if answer.startswith("robot did not apply"):
        return f"**Robot answered STOP** after {took_s:.1f} s: {answer.removeprefix('robot ')}"
    return f"**Robot confirmed STOP** after {took_s:.1f} s: {state}"


class StopHeader:
    """STOP, its acknowledgement, the robot's state and "Back away" (see the module docstring)."""

    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.session = session
        self.actions = actions
        self._clock = clock
        gui = server.gui
        self.stop = gui.add_button("STOP", color="red", icon=viser.Icon.PLAYER_STOP,
                                   hint="stop the robot now (it waits for resume, skip or abort)")
        self.stop.on_click(lambda _: self.press_stop())
        self.state = gui.add_html(state_html(None))
        self.ack = gui.add_markdown("")
        self.back_away = gui.add_button(
            "Back away", color="orange", icon=viser.Icon.ARROW_BACK_UP, visible=False,
            hint="after a contact: abort what is left, then move the tool 30 mm back the way it came (or up), slowly",
        )
        self.back_away.on_click(lambda _: self.actions.run("back away", self.session.recovery.back_away))
        self._sent_at: float | None = None  # when the STOP we wait for left (clock)
        self._seen_pending = False
        self._answer = ""  # the robot's answer to it, from the notice
        self._answered = False  # the answer is shown and stands until the robot runs again
        self._rested = False  # the robot was seen at rest since the answer

    def press_stop(self) -> None:
        self._sent_at, self._seen_pending, self._answer = self._clock(), False, ""
        self._answered = self._rested = False
        link = self.actions.run("stop", self.session.recovery.stop)
        if link is None:  # refused (no robot): the notice line says why
            self._sent_at = None
            return
        self.ack.content = stop_sent_text(link)

    # -- session events -----------------------------------------------------------------------
    def show_link(self, link: LinkView) -> None:
        shown = state_html(link)
        if self.state.content != shown:  # link updates come 4 times a second: send only changes
            self.state.content = shown
        fault = link.connected and link.robot_state == "fault"
        if self.back_away.visible != fault:
            self.back_away.visible = fault
        if self._sent_at is None:
            if self._answered:
                self._clear_answer_when_running(link)
            return
        if "stop" in link.recovery_pending:
            self._seen_pending = True
            return
        if self._seen_pending:  # its answer is back
            self.ack.content = stop_answer_text(self._answer, self._clock() - self._sent_at, link)
            self._sent_at = None
            self._answered, self._rested = True, False
            self._clear_answer_when_running(link)

    def _clear_answer_when_running(self, link: LinkView) -> None:
        """The answer to STOP describes a robot held by it: once the robot has been seen held
        (stopped, at fault) and then leaves that hold (a resume: running again, or idle with
        nothing to run; a skip; an abort), the answer is over (the notice log keeps it)."""
        state = link.robot_state if link.connected else None
        if state in ("stopped", "fault"):
            self._rested = True
        elif state in ("running", "idle") and self._rested:
            self.ack.content = ""
            self._answered = False

    def show_notice(self, notice: Notice) -> None:
        """Keep the robot's answer to the STOP we wait for (the session says it in a notice)."""
        message = notice.message
        if self._sent_at is not None and (message.startswith("robot applied stop") or message.startswith("robot did not apply stop")
                                          or message.startswith("stop failed")):
            self._answer = message
