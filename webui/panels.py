"""The driving panel (thesis 4.3.4): moving part, frame, constraint, motion, joint sliders, and
a transform gizmo on the tool point. Every control turns into a ``Session`` call."""

from __future__ import annotations

import logging

import numpy as np
import viser
import viser.transforms as vtf

from server.session import Session, VirtualState
from shared.robots.jog import CONSTRAINTS, FRAME_NAMES, MOTIONS
from webui.scene import FRAME_AXES, CellScene

log = logging.getLogger(__name__)

TOOL = "Tool"


def _matrix(wxyz: np.ndarray, position: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = vtf.SO3(np.asarray(wxyz)).as_matrix()
    out[:3, 3] = position
    return out


class DrivePanel:
    """GUI controls for driving the virtual arm."""

    def __init__(self, server: viser.ViserServer, session: Session, scene: CellScene) -> None:
        self.server = server
        self.session = session
        robot = session.robot
        gui = server.gui
        with gui.add_folder("Drive"):
            self.part = gui.add_dropdown("Moving part", [TOOL] + [f"J{i}" for i in range(1, robot.dof + 1)], initial_value=TOOL)
            self.frame = gui.add_dropdown("Frame", list(FRAME_NAMES), initial_value="world")
            self.constraint = gui.add_dropdown("Direction", list(CONSTRAINTS), initial_value="xy")
            self.motion = gui.add_dropdown("Motion", list(MOTIONS), initial_value="translate")
            self.status = gui.add_markdown("")
        with gui.add_folder("Joints (deg)"):
            self.sliders: list[viser.GuiInputHandle[float]] = []
            q = session.state.q
            for i in range(robot.dof):
                slider = gui.add_slider(
                    f"J{i + 1}", min=float(np.degrees(robot.lower[i])), max=float(np.degrees(robot.upper[i])),
                    step=0.1, initial_value=float(np.degrees(q[i])),
                )
                slider.on_update(self._slider_callback(i + 1))
                self.sliders.append(slider)
        with gui.add_folder("Frames", expand_by_default=False):
            for name in FRAME_AXES:
                box = gui.add_checkbox(f"Show {name}", initial_value=False)
                box.on_update(lambda event, name=name: scene.set_axes_visible(name, bool(event.target.value)))
        state = session.state
        self.gizmo = server.scene.add_transform_controls(
            "/tool_gizmo", scale=0.18, wxyz=vtf.SO3.from_matrix(state.world_T_tcp[:3, :3]).wxyz,
            position=state.world_T_tcp[:3, 3],
        )
        self._dragging = False
        self.gizmo.on_update(self._on_gizmo)
        self.part.on_update(lambda _: self._refresh_gizmo())
        self.motion.on_update(lambda _: self._refresh_gizmo())
        self._refresh_gizmo()
        session.subscribe(self._on_state)
        self._on_state(state)

    # -- callbacks ---------------------------------------------------------------------------
    def _slider_callback(self, joint: int):
        def callback(event: viser.GuiEvent) -> None:
            if event.client is None:  # our own programmatic update
                return
            self.session.set_joint(joint, float(np.radians(event.target.value)))

        return callback

    def _on_gizmo(self, event) -> None:
        phase = getattr(event, "phase", "update")
        if phase == "start":
            self._dragging = True
            return
        if phase == "end":
            self._dragging = False
            self._snap_gizmo(self.session.state)
            return
        if self.part.value != TOOL:
            return
        goal = _matrix(self.gizmo.wxyz, self.gizmo.position)
        self.session.jog_tool_to(
            goal, frame=self.frame.value, constraint=self.constraint.value, motion=self.motion.value
        )

    def _refresh_gizmo(self) -> None:
        tool = self.part.value == TOOL
        self.gizmo.visible = tool
        self.gizmo.disable_rotations = self.motion.value != "rotate"
        self.gizmo.disable_axes = self.motion.value == "rotate"
        self.gizmo.disable_sliders = self.motion.value == "rotate"

    def _snap_gizmo(self, state: VirtualState) -> None:
        self.gizmo.wxyz = vtf.SO3.from_matrix(state.world_T_tcp[:3, :3]).wxyz
        self.gizmo.position = state.world_T_tcp[:3, 3]

    def _on_state(self, state: VirtualState) -> None:
        for slider, value in zip(self.sliders, np.degrees(state.q)):
            slider.value = float(round(value, 1))
        if not self._dragging:
            self._snap_gizmo(state)
        x, y, z = state.world_T_tcp[:3, 3] * 1e3
        text = f"Tool (world): x {x:.1f} mm, y {y:.1f} mm, z {z:.1f} mm"
        if state.last_jog is not None and state.last_jog.blocked:
            text += f"\n\n**Blocked ({state.last_jog.blocked}):** {state.last_jog.message}"
        self.status.content = text
