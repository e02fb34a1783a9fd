"""The Terrain tab of a rover cell (seed 004): the arm's clearance over the ground by both
checks, the virtual sensors on demand, and instrument placement at a target picked by clicking
the terrain (or typed as a ground position), with its program inserted on request.

Every control calls the session; the placement itself (IK, clearances, program) is computed by
``shared.terrain`` behind ``session.terrain.place_instrument``.
"""

from __future__ import annotations

import logging

import viser

from server.console import PlacementView, Session, TerrainView
from webui.actions import Actions

log = logging.getLogger(__name__)


def _mm(value: float | None) -> str:
    return "no reading" if value is None else f"{value * 1e3:.1f} mm"


def clearance_markdown(view: TerrainView) -> str:
    """Both checks in a few lines: exact distance and where, the head, the sensors."""
    if view.in_collision:
        lines = [f"**ARM TOUCHES THE GROUND** ({view.shape}); {len(view.contact_corners)} triangle(s) in red"]
    else:
        lines = [f"Exact clearance: **{_mm(view.distance)}** ({view.shape or 'arm'})"]
    lines.append(f"Instrument head to ground: {_mm(view.head_distance)}")
    sensor = "collision" if view.sensor_collision else _mm(view.sensor_distance)
    lines.append(f"Virtual sensors: {sensor}")
    return "  \n".join(lines)


def placement_markdown(view: PlacementView | None) -> str:
    if view is None:
        return "No target yet: tick *Pick target on click* and click the terrain, or type a ground position."
    x, y, z = (v * 1e3 for v in view.world_p_target)
    lines = [f"Target ({x:.1f}, {y:.1f}, {z:.1f}) mm: {view.message}"]
    for k, c in enumerate(view.candidates[:4]):
        q = ", ".join(f"{v:.1f}" for v in c.q_deg)
        lines.append(f"{k + 1}: ({q}) deg, clearance {c.clearance * 1e3:.1f} mm, standoff {c.standoff * 1e3:.1f} mm"
                     f"{'' if c.approach else ', no approach pose'}")
    if view.program:
        lines.append("Program: " + " / ".join(f"`{t}`" for t in view.program))
    return "  \n".join(lines)


class TerrainPanel:
    """Controls of the terrain tab; redrawn from ``TerrainChanged`` / ``PlacementChanged``."""

    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions) -> None:
        self.server = server
        self.session = session
        self.actions = actions
        gui = server.gui
        self.clearance = gui.add_markdown("")
        self.sensors = gui.add_checkbox("Show virtual sensors", initial_value=False,
                                        hint="the seed-004 sensor segments on every arm part (red: ray meets the ground)")
        self.sensors.on_update(self._on_sensors)
        with gui.add_folder("Instrument placement"):
            self.pick = gui.add_checkbox("Pick target on click", initial_value=False,
                                         hint="the next clicks on the terrain choose the target")
            self.pick.on_update(self._on_pick_mode)
            self.ground_x = gui.add_number("Target x (mm)", initial_value=700.0, step=1.0)
            self.ground_y = gui.add_number("Target y (mm)", initial_value=-100.0, step=1.0)
            self.plan = gui.add_button("Plan at ground position", icon=viser.Icon.TARGET)
            self.plan.on_click(self._on_plan)
            self.result = gui.add_markdown(placement_markdown(None))
            self.insert = gui.add_button("Insert placement program", icon=viser.Icon.ROW_INSERT_TOP, disabled=True)
            self.insert.on_click(lambda _: self.actions.run("insert the placement program", self.session.terrain.insert_placement))
            self.goto = gui.add_button("Show best configuration", icon=viser.Icon.EYE, disabled=True)
            self.goto.on_click(lambda _: self.actions.run("show the best configuration", lambda: self.session.terrain.goto_placement(0)))
        self._clicking = False

    # -- callbacks ---------------------------------------------------------------------------
    def _on_sensors(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.actions.run("show the virtual sensors", lambda: self.session.terrain.set_sensors(bool(self.sensors.value)))

    def _on_pick_mode(self, event: viser.GuiEvent) -> None:
        on = bool(self.pick.value)
        if on and not self._clicking:
            self.server.scene.on_click()(self._on_scene_click)
            self._clicking = True
        elif not on and self._clicking:
            self.server.scene.remove_click_callback(self._on_scene_click)
            self._clicking = False

    def _on_scene_click(self, event) -> None:
        ray = (tuple(event.ray_origin), tuple(event.ray_direction))
        self.actions.run("place the instrument", lambda: self.session.terrain.place_instrument(ray=ray))

    def _on_plan(self, _event: viser.GuiEvent) -> None:
        xy = (float(self.ground_x.value) * 1e-3, float(self.ground_y.value) * 1e-3)
        self.actions.run("place the instrument", lambda: self.session.terrain.place_instrument(ground_xy=xy))

    # -- drawing -----------------------------------------------------------------------------
    def show(self, view: TerrainView) -> None:
        self.clearance.content = clearance_markdown(view)
        if self.sensors.value != (view.sensors is not None):
            self.sensors.value = view.sensors is not None

    def show_placement(self, view: PlacementView | None) -> None:
        self.result.content = placement_markdown(view)
        has = view is not None and bool(view.candidates)
        self.insert.disabled = not has
        self.goto.disabled = not has
