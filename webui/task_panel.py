"""The Task tab (thesis 3.5, issue 18): what the task net makes of the operator's work.

* the actions recognised on the virtual cell, one per line, as they are recognised while driving;
  during a preview, the actions the previewed range makes up to the player's time;
* a picture of the task space's net (a place per atom, a transition per ground action) with the
  marking where the virtual cell (or the preview player) stands: marked places shaded, a token;
* the robot's marking and the actions its reports made, and every task deviation in red with
  the transition that was expected;
* Save buttons for the net generated from the recognised actions (PNML, JSON, PNG);
* task-level commands (issue 40): a button for each action the virtual marking enables, and a
  goal box (atoms typed, or picked from the net's places) whose Plan button inserts the whole plan;
  the lines they insert are ordinary program lines, marked with their action
  (``server.console.task_commands``).

The recognition is the session's (``server.console.task_monitor``); this module only draws its
``TaskView``. The net picture comes from ``shared.tasknet.layout``, the same drawing as
``teleprog net show --svg``.
"""

from __future__ import annotations

import html
import re

import numpy as np
import viser

from server.console import Session
from server.console.views import ActionView, DeviationView, TaskView
from shared.tasknet.cenet import ConditionEventModel, from_condition_event_model
from shared.tasknet.jsonform import net_to_json
from shared.tasknet.layout import net_to_svg
from shared.tasknet.pnml import net_to_pnml
from shared.tasknet.raster import net_to_png
from shared.tasknet.ptnet import PTNet
from webui.actions import Actions

DEVIATION_RED = "#c62828"


def _action_items(actions: list[ActionView], kind: str) -> str:
    if not actions:
        return '<div style="opacity:.7">none yet</div>'
    rows = []
    for i, a in enumerate(actions):
        where = f" (statement {a.statement})" if a.statement is not None else ""
        rows.append(f'<li data-action="{html.escape(a.action)}" data-kind="{kind}"><code>{html.escape(a.action)}</code>'
                    f'<span style="opacity:.7">{html.escape(where)}</span></li>')
    return f'<ol data-actions="{kind}" style="margin:2px 0 4px 18px;padding:0">{"".join(rows)}</ol>'


def _marking(atoms: list[str], kind: str) -> str:
    text = ", ".join(html.escape(a) for a in atoms) or "(empty)"
    return f'<div data-marking="{kind}" data-atoms="{html.escape("|".join(atoms))}"><code>{{{text}}}</code></div>'


def _deviation(d: DeviationView) -> str:
    expected = f"<div>expected: <code>{html.escape(d.expected)}</code></div>" if d.expected else ""
    return (f'<div data-deviation="{d.kind}" data-expected="{html.escape(d.expected or "")}" '
            f'style="border:2px solid {DEVIATION_RED};color:{DEVIATION_RED};border-radius:4px;padding:3px 6px;margin:3px 0">'
            f"<b>Task deviation</b>: {html.escape(d.message)}{expected}</div>")


def task_html(view: TaskView, picture: str = "") -> str:
    """The Task tab's block for ``view``; ``picture`` is the net's SVG."""
    if not view.available:
        why = f": {view.error}" if view.error else " (no assets/tasks/<cell>.toml)"
        return f'<div data-task="off">No task model for this cell{html.escape(why)}.</div>'
    parts = [f'<div data-task="{html.escape(view.task or "")}" data-version="{view.version}" style="font-size:13px">']
    if view.deviations:
        parts += [_deviation(d) for d in view.deviations[-5:]]
    if view.preview_active:
        parts.append("<b>Preview</b>: actions of the previewed range up to the player")
        parts.append(_action_items(view.preview_actions, "preview"))
        parts.append("Marking where the player stands:")
        parts.append(_marking(view.preview_marking, "preview"))
    parts.append("<b>Recognised on the virtual cell</b>")
    parts.append(_action_items(view.virtual_actions, "virtual"))
    parts.append("Marking:")
    parts.append(_marking(view.virtual_marking, "virtual"))
    if view.enabled:
        parts.append('<div style="opacity:.8">enabled: ' + ", ".join(f"<code>{html.escape(e)}</code>" for e in view.enabled) + "</div>")
    parts.append(f'<div style="margin-top:4px">{picture}</div>')
    parts.append("<b>The robot</b> (from its reports)")
    parts.append(_action_items(view.robot_actions, "robot"))
    parts.append(_marking(view.robot_marking, "robot"))
    parts.append("</div>")
    return "".join(parts)


NET_LABEL_PX = 12  # the net's SVG labels (``shared.tasknet.layout``) at its natural size
MIN_LABEL_PX = 11  # the smallest the page may draw them


def net_picture(net: PTNet, true_atoms: list[str], planned: list[str] | None = None) -> str:
    """The net as SVG, marked where ``true_atoms`` hold, the ``planned`` path of actions (the
    program's task lines) drawn in blue and numbered, scaled to the panel's width."""
    marked = set(true_atoms)
    m = np.array([1 if p.predicate in marked else 0 for p in net.places], dtype=np.int64)
    svg = net_to_svg(net, m, planned or ())
    natural = float(re.search(r'<svg [^>]*?width="([\d.]+)"', svg).group(1))
    # as wide as the panel, but never so small that its 12 px labels read under MIN_LABEL_PX: a
    # wide net scrolls sideways instead (scaled to a 400 px panel, a 1,200 px net's labels were 4 px)
    least = natural * MIN_LABEL_PX / NET_LABEL_PX
    svg = re.sub(r'<svg ([^>]*?)width="[^"]+" height="[^"]+"',
                 rf'<svg \1width="100%" style="min-width:{least:.0f}px"', svg, count=1)
    return f'<div data-task-net style="width:100%;overflow:auto">{svg}</div>'


class TaskPanel:
    """The Task tab's widgets, added where the caller's GUI context is."""

    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions) -> None:
        self.session, self.actions = session, actions
        gui = server.gui
        self._space: tuple[ConditionEventModel, PTNet] | None = None
        self.block = gui.add_html(task_html(session.task.view()))
        self.save_pnml = gui.add_button("Save task net (PNML)", disabled=not session.task.available)
        self.save_json = gui.add_button("Save task net (JSON)", disabled=not session.task.available)
        self.save_png = gui.add_button("Save task net (PNG)", disabled=not session.task.available)
        self.save_pnml.on_click(lambda e: self._save(e, "pnml"))
        self.save_json.on_click(lambda e: self._save(e, "json"))
        self.save_png.on_click(lambda e: self._save(e, "png"))
        self._gui = gui
        self._buttons: dict[str, viser.GuiButtonHandle] = {}
        self._offered_for: tuple | None = None  # (the program's state, the virtual marking) the buttons show
        self._planned: list[str] = []  # the actions the program's task lines serve: the net's planned path
        self._view: TaskView | None = None
        self.commands = None
        if session.task.available:
            view = session.task.view()
            with gui.add_folder("Plan by task") as folder:
                self.commands = folder
                self.goal = gui.add_text("Goal", initial_value="", hint="atoms, e.g. PEGINHOLE(PEG,HOLE2); several: comma")
                self.pick = gui.add_dropdown("Add place", options=("(pick a place)", *view.atoms))
                self.plan = gui.add_button("Plan goal", hint="insert the actions that reach the goal from the virtual cell")
                self.offered_label = gui.add_markdown("Actions enabled where the program ends:")
            self.pick.on_update(lambda _e: self._picked())
            self.plan.on_click(lambda e: self._plan_goal(e))
            self.sync_commands()

    # -- task-level commands -----------------------------------------------------------------
    def _picked(self) -> None:
        atom = self.pick.value
        if atom.startswith("("):
            return
        now = self.goal.value.strip()
        if atom not in now:
            self.goal.value = f"{now}, {atom}" if now else atom
        self.pick.value = "(pick a place)"

    def _plan_goal(self, event: viser.GuiEvent) -> None:
        goal = self.goal.value.strip()  # atoms, read by the task space's own parser (commas inside atoms too)
        if not goal:
            self.actions.show_notice("warning", "type a goal first (an atom of the task net, e.g. PEGINHOLE(PEG,HOLE2))", None)
            return
        done = self.actions.run("plan goal", lambda: self.session.task_commands.goal(goal, client=None))
        if done is not None and done.plan is not None:
            inserted = [r.action for r in done.rows]
            later = (f"; {', '.join(done.deferred)} after the robot reports the insertion (plan the goal again then)"
                     if done.deferred else "")
            self.actions.show_notice("warning" if done.warnings else "info",
                                     f"inserted {', '.join(inserted) or 'nothing (the goal holds)'} "
                                     f"({sum(len(r.statements) for r in done.rows)} statements){later}"
                                     + (f"; the preview's check: {'; '.join(done.warnings)}" if done.warnings else ""), None)

    def _take_action(self, text: str) -> None:
        done = self.actions.run("task action", lambda: self.session.task_commands.action(text, client=None))
        if done is not None:
            self.actions.show_notice("warning" if done.warnings else "info",
                                     f"inserted {text} ({len(done.rows[0].statements)} statements)"
                                     + (f"; the preview's check: {'; '.join(done.warnings)}" if done.warnings else ""), None)

    def sync_commands(self) -> None:
        """One button per action enabled where the program leaves the virtual cell, in the task
        space's order; asked again only when the program or the virtual marking changed (the tab
        is redrawn at every step of a preview's player)."""
        if self.commands is None:
            return
        key = (self.session.program.state, tuple(self.session.task.view().virtual_marking))
        if key == self._offered_for:
            return
        offered = self.session.task_commands.offered(wait=False)  # never hold the page's events for a play
        if offered is None:
            return  # a play is under way: the next event asks again
        self._offered_for = key
        planned = self.session.program.planned_actions()
        if planned != self._planned:
            self._planned = planned
            if self._view is not None and (net := self._net(self._view)) is not None:  # the path redrawn
                v = self._view
                self.block.content = task_html(v, net_picture(net, v.preview_marking if v.preview_active else v.virtual_marking,
                                                              planned))
        if list(self._buttons) == offered:
            return
        for button in self._buttons.values():
            button.remove()
        self._buttons = {}
        with self.commands:
            for text in offered:
                button = self._gui.add_button(text, hint=f"insert the statements of {text}")
                button.on_click(lambda _e, t=text: self._take_action(t))
                self._buttons[text] = button

    def _net(self, view: TaskView) -> PTNet | None:
        model = view.space_net
        if model is None:
            return None
        if self._space is None or self._space[0] != model:
            self._space = (model, from_condition_event_model(model, net_id=view.task or "task"))
        return self._space[1]

    def show(self, view: TaskView) -> None:
        net = self._net(view)
        self._view = view
        self.sync_commands()
        picture = "" if net is None else net_picture(net, view.preview_marking if view.preview_active else view.virtual_marking,
                                                     self._planned)
        self.block.content = task_html(view, picture)

    def _save(self, event: viser.GuiEvent, kind: str) -> None:
        net = self.session.task.generated_net()
        if net is None or event.client is None:
            return
        if kind == "png":
            content = net_to_png(net)
        else:
            content = (net_to_pnml(net) if kind == "pnml" else net_to_json(net)).encode("utf-8")
        event.client.send_file_download(f"task_net.{kind}", content, save_immediately=True)
        self.actions.show_notice("info", f"saved the task net ({len(net.places)} places, {len(net.transitions)} transitions) "
                                 f"as task_net.{kind}", None)
