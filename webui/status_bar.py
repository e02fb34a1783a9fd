"""Under STOP in the console's header (``webui.stop_header``), always in view: recovery, the
link, the regime, who holds control (and who asks for it), the display mode, a divergence warning
with its re-sync, and the last notice (a refused operation names its rule).

Why at the top and outside any tab or folder: over a delayed link the operator must be able to
stop the robot with one click whatever panel is open, and must always know how old the picture
of the robot is (thesis 4.4: the delay only hurts when recovering, so recovery is never hidden).
"""

from __future__ import annotations

import logging
import time

import viser

from server.console import (
    ControlView,
    DisplayMode,
    DivergenceView,
    LinkView,
    Notice,
    Regime,
    RegimeView,
    Session,
    WorkProgress,
)
from webui.actions import Actions
from webui.notice_log import NoticeBoard, session_kind

log = logging.getLogger(__name__)

RECOVERY_STATES = {
    "Resume": frozenset({"stopped", "fault"}),
    "Skip": frozenset({"running", "stopped", "fault"}),
    "Abort": frozenset({"running", "stopped", "fault"}),
}
"""The robot states (as telemetry shows them) in which each recovery button is on: Resume only
for a robot held by a stop, a halt or a fault; Skip and Abort for one with a statement at hand.
Idle, disconnected or without telemetry, none is (there is nothing they would act on)."""
AUTO = "auto (by zone)"
REGIME_LABELS = {Regime.FREE: "ONLINE (free zone)", Regime.QUASI: "OFFLINE (quasi-operation)",
                 Regime.OPERATION: "SINGLE STEP (operation)"}
REGIME_BY_LABEL = {label: regime for regime, label in REGIME_LABELS.items()}


def regime_option(value: str) -> str:
    """The Regime selector's option for a regime's value (``free`` -> ``ONLINE (free zone)``):
    the operator reads the regime's name and zone, never the API's raw value."""
    return REGIME_LABELS[Regime(value)] if value in Regime._value2member_map_ else value


MODE_LABELS = {DisplayMode.TELEPROGRAMMING: "teleprogramming", DisplayMode.TASK_PREVIEW: "task preview",
               DisplayMode.TELEPRESENCE: "telepresence"}


def _seconds(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f} s"


def link_text(link: LinkView) -> str:
    """One line the operator reads: connected or not, measured delay, age of the telemetry."""
    if not link.configured:
        return "Link: **no robot configured** (console alone)"
    state = "connected" if link.connected else "**NOT CONNECTED**"
    parts = [f"Link: {state}"]
    if link.delay_s is not None:
        parts.append(f"delay {link.delay_s * 1e3:.0f} ms")
    parts.append(f"telemetry {_seconds(link.telemetry_age_s)} old")
    if link.robot_state:
        parts.append(f"robot **{link.robot_state}**")
    if link.recovery_pending:
        parts.append("waiting for " + ", ".join(link.recovery_pending))
    parts += [f"**{problem}**" for problem in link.problems]
    return " · ".join(parts)


def regime_text(view: RegimeView) -> str:
    how = "operator override" if view.override is not None else "by zone"
    return f"Regime: **{REGIME_LABELS[view.regime]}** ({how}); zone: {view.zone.value}"


def control_text(view: ControlView) -> str:
    """Who may change the session: nobody holding control, anybody (this page too); a holder,
    only it, and this page observes; a request waiting on the holder, with when it passes."""
    if view.holder is None:
        return "Control: **free**: this page may act"
    text = f"Control: **{view.holder}** holds it; this page observes"
    if view.asked is not None:
        passes = time.strftime("%H:%M:%S", time.localtime(view.asked.passes_at))
        text += f" · **{view.asked.by}** asks for it (passes at {passes} unless {view.holder} refuses)"
    return text


class StatusBar:
    """Recovery, link, regime, control and mode selectors, divergence, notices."""

    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions, board: NoticeBoard | None = None) -> None:
        self.server = server
        self.session = session
        self.actions = actions
        gui = server.gui
        # each on only when it can act on what the operator sees (``RECOVERY_STATES``)
        self.recovery = {
            name: gui.add_button(name, disabled=True, hint=hint)
            for name, hint in (("Resume", "let the stopped robot go on with what it holds"),
                               ("Skip", "drop the statement the robot runs or holds now"),
                               ("Abort", "drop the current statement and everything the robot holds"))
        }
        for button in self.recovery.values():
            button.on_click(self._on_recovery)
        self.link = gui.add_markdown("Link: -")
        self.regime_line = gui.add_markdown("Regime: -")
        self.control_line = gui.add_markdown(control_text(session.control.view()))
        self.regime = gui.add_dropdown("Regime", [AUTO] + [REGIME_LABELS[r] for r in Regime], initial_value=AUTO)
        self.regime.on_update(self._on_regime)
        self.mode = gui.add_dropdown("Display", [m.value for m in DisplayMode],
                                     initial_value=DisplayMode.TELEPROGRAMMING.value)
        self.mode.on_update(self._on_mode)
        self.divergence = gui.add_markdown("", visible=False)
        self.resync = gui.add_button("Re-sync from robot", color="orange", visible=False,
                                     hint="put the virtual arm and moved objects where the robot reports them")
        self.resync.on_click(lambda _: self.actions.run("re-sync", self.session.resync))
        # long work off the console's loop (a program file's load, the task's replay): a line
        # and a bar while it runs, gone when it ends
        self.work_line = gui.add_markdown("", visible=False)
        self.work_bar = gui.add_progress_bar(0.0, visible=False, animated=False)
        self._works: dict[int, WorkProgress] = {}
        self.notice = gui.add_markdown("")
        self.board = board if board is not None else NoticeBoard()
        with gui.add_folder("Notice log", expand_by_default=False):
            self.log = gui.add_html(self.board.log_html())
        self._setting = False  # True while we write a selector ourselves (no echo to the session)

    # -- clicks -------------------------------------------------------------------------------
    def _on_recovery(self, event: viser.GuiEvent) -> None:
        choice = event.target.label
        call = {"Resume": self.session.recovery.resume, "Skip": self.session.recovery.skip, "Abort": self.session.recovery.abort}[choice]
        self.actions.run(choice.lower(), call)

    def _on_regime(self, event: viser.GuiEvent) -> None:
        if self._setting or event.client is None:
            return
        override = REGIME_BY_LABEL.get(self.regime.value)  # None: auto
        self.actions.run("regime override", lambda: self.session.modes.set_regime_override(override))

    def _on_mode(self, event: viser.GuiEvent) -> None:
        if self._setting or event.client is None:
            return
        mode = DisplayMode(self.mode.value)
        self.actions.run("display mode", lambda: self.session.modes.set_display_mode(mode))

    # -- session events -----------------------------------------------------------------------
    def show_link(self, link: LinkView) -> None:
        self.link.content = link_text(link)
        state = link.robot_state if link.connected else None
        self.board.robot_state(state)
        for name, button in self.recovery.items():
            off = state not in RECOVERY_STATES[name]
            if button.disabled != off:
                button.disabled = off

    def show_regime(self, view: RegimeView) -> None:
        self.regime_line.content = regime_text(view)
        wanted = AUTO if view.override is None else REGIME_LABELS[view.override]
        if self.regime.value != wanted:
            self._setting = True
            try:
                self.regime.value = wanted
            finally:
                self._setting = False

    def show_control(self, view: ControlView) -> None:
        self.control_line.content = control_text(view)

    def show_mode(self, mode: DisplayMode) -> None:
        if self.mode.value != mode.value:
            self._setting = True
            try:
                self.mode.value = mode.value
            finally:
                self._setting = False

    def show_divergence(self, view: DivergenceView) -> None:
        if view.diverged:
            text = view.message or (
                f"virtual and remote arm differ: tool {view.tool_error * 1e3:.1f} mm, "
                f"joints {view.joint_error * 57.29577951308232:.2f} deg"
            )
            self.divergence.content = f"**Divergence:** {text}"
        self.divergence.visible = view.diverged
        self.resync.visible = view.diverged

    def show_work(self, event: WorkProgress) -> None:
        """The newest work still running, with its step and how much is done; none: hidden."""
        if event.finished:
            self._works.pop(event.id, None)
        else:
            self._works[event.id] = event
        running = max(self._works.values(), key=lambda w: w.id, default=None)
        if running is None:
            self.work_line.visible = self.work_bar.visible = False
            return
        others = f" (and {len(self._works) - 1} more)" if len(self._works) > 1 else ""
        self.work_line.content = f"**{running.what[:1].upper()}{running.what[1:]}**: {running.phase}, {running.fraction:.0%}{others}"
        self.work_bar.value = 100.0 * running.fraction
        self.work_line.visible = self.work_bar.visible = True

    def show_notice(self, level: str, message: str, rule: str | None = None) -> None:
        """A notice the session said (or a caller without a kind): it stands until its kind's
        condition ends (``webui.notice_log``)."""
        self.board.post(level, message, rule, session_kind(level, message), refused=level == "error" and rule is not None)

    def show_notice_event(self, notice: Notice) -> None:
        self.show_notice(notice.level, notice.message, notice.rule)

    def render_notices(self) -> None:
        """Draw the standing notice and the log from the board (after every change of it)."""
        line = self.board.line_markdown()
        if self.notice.content != line:
            self.notice.content = line
        shown = self.board.log_html()
        if self.log.content != shown:
            self.log.content = shown
