"""The preview panel (thesis 4.3.6-4.3.7, task preview): choose a range of statements, then
play, pause, step and scrub it on the virtual arm; collision and joint-limit warnings listed.

The session plays the range with the telerobot's own interpreter and planner and reports where
the arm is at each moment; the panel only sends the operator's choices and shows the result.
The program is not changed; while a preview runs the editor allows only selection. The preview
speed (1x, 2x, 5x, 10x or instant) is the session's: Play and "Preview and submit" use it.
"""

from __future__ import annotations

import viser

from server.console import PreviewView, ProgramView, Session
from webui.actions import Actions
from webui.statement_range import StatementRange


SPEEDS: dict[str, float | str] = {"1x": 1.0, "2x": 2.0, "5x": 5.0, "10x": 10.0, "instant": "instant"}


def speed_label(speed: float | str) -> str:
    return "instant" if speed == "instant" else f"{float(speed):g}x"


def warnings_markdown(view: PreviewView) -> str:
    if not view.active:
        return "No preview running."
    lines = [f"Statements {view.start + 1}-{view.stop}: t = {view.t:.2f} / {view.duration:.2f} s"
             + (" (playing)" if view.playing else " (paused)")]
    if view.current is not None:
        lines.append(f"Playing statement {view.current + 1}")
    if view.colliding_now:
        lines.append("**COLLISION at this moment**")
    if view.refusal:
        lines.append(f"**Planning stopped:** {view.refusal}")
    for w in view.warnings[:8]:
        lines.append(f"**{w.kind.replace('_', ' ')}** at {w.t:.2f} s (statement {w.index + 1}): {w.message}")
    if len(view.warnings) > 8:
        lines.append(f"... and {len(view.warnings) - 8} more warnings")
    if not view.warnings and not view.refusal:
        # one answer, never two: a pose that touches something now is not "no warnings"
        lines.append("No warnings along the range's path; the pose shown touches something." if view.colliding_now
                     else "No warnings.")
    return "  \n".join(lines)


class PreviewPanel:
    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions) -> None:
        self.server = server
        self.session = session
        self.actions = actions
        gui = server.gui
        self.range = StatementRange(gui, "From statement", "To statement")
        self.start = gui.add_button("Start preview", icon=viser.Icon.EYE)
        self.start.on_click(self._on_start)
        self.speed = gui.add_dropdown("Preview speed", list(SPEEDS), initial_value="1x",
                                      hint="plan time per second of playing; instant: checked at once, stands at the end")
        self.speed.on_update(self._on_speed)
        self.controls = gui.add_button_group("Player", ("Play", "Pause", "Step", "End"))
        self.controls.on_click(self._on_control)
        self.time = gui.add_slider("Preview time (s)", min=0.0, max=1.0, step=0.01, initial_value=0.0, disabled=True)
        self.time.on_update(self._on_scrub)
        self.report = gui.add_markdown("No preview running.")
        self._setting = False

    # -- clicks -------------------------------------------------------------------------------
    def _on_start(self, _event: viser.GuiEvent) -> None:
        start, stop = self.range.slice()
        self.actions.run("preview", lambda: self.session.preview.begin(start, stop))

    def _on_control(self, event: viser.GuiEvent) -> None:
        choice = event.target.value
        call = {
            "Play": self.session.preview.play,
            "Pause": self.session.preview.pause,
            "Step": self.session.preview.step,
            "End": self.session.preview.end,
        }[choice]
        self.actions.run(f"preview {choice.lower()}", call)

    def _on_speed(self, event: viser.GuiEvent) -> None:
        if self._setting or event.client is None:
            return
        speed = SPEEDS[self.speed.value]
        self.actions.run("preview speed", lambda: self.session.preview.set_speed(speed))

    def _on_scrub(self, event: viser.GuiEvent) -> None:
        if self._setting or event.client is None:
            return
        t = float(self.time.value)
        self.actions.run("preview scrub", lambda: self.session.preview.seek(t))

    # -- session events -----------------------------------------------------------------------
    def show_program(self, view: ProgramView) -> None:
        self.range.follow(view)

    def show(self, view: PreviewView) -> None:
        self.report.content = warnings_markdown(view)
        self._setting = True
        try:
            label = speed_label(view.speed)
            if label in SPEEDS and self.speed.value != label:
                self.speed.value = label
            self.time.disabled = not view.active
            if view.active:
                top = max(view.duration, 0.01)
                if abs(self.time.max - top) > 1e-9:
                    self.time.max = top
                self.time.value = min(round(view.t, 2), top)
        finally:
            self._setting = False
