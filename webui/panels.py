"""The driving panel (thesis 4.3.4): moving part, frame, direction constraint (one axis or one
plane), translate or rotate, whether driving generates statements, a slider per joint, frames
on demand, and a transform gizmo (``webui.drive_gizmo``: the handles the choice allows, in the
chosen frame; a ring on a chosen joint). Every control turns into a session call; a blocked
motion shows why, and a collision while driving shows as a warning here and red triangles in
the scene.
"""

from __future__ import annotations

import logging
import threading

import numpy as np
import viser

from server.console import ArmView, CollisionView, ProgramView, Session
from shared.robots.jog import CONSTRAINTS, FRAME_NAMES, MOTIONS
from webui.actions import Actions
from webui.drive_gizmo import DriveGizmo
from webui.scene import FRAME_AXES, CellScene

log = logging.getLogger(__name__)

TOOL = "Tool"
SLIDER_RELEASE_S = 0.4
AXES = tuple(c for c in CONSTRAINTS if len(c) == 1)
PLANES = tuple(c for c in CONSTRAINTS if len(c) == 2)


def direction_label(constraint: str) -> str:
    return f"{constraint} axis" if len(constraint) == 1 else f"{constraint} plane"


WRITTEN_SHOWN = 3  # the program's last statements the Drive tab shows


def written_markdown(view: ProgramView) -> str:
    """What the Drive tab says of the statements being written: the program's last ones, newest
    last, so the operator sees each drag become a statement without leaving the tab."""
    if not view.auto_generate:
        return "Writing: off (drags move the virtual arm only)"
    last = view.entries[:view.empty_index][-WRITTEN_SHOWN:]
    if not last:
        return "Writing: nothing yet; a drag, let go, becomes a statement"
    first = view.empty_index - len(last) + 1
    return "Written last:  \n" + "  \n".join(f"{first + i}: `{e.text}`" for i, e in enumerate(last))


class DrivePanel:
    """GUI controls for driving the virtual arm."""

    def __init__(self, server: viser.ViserServer, session: Session, scene: CellScene, actions: Actions) -> None:
        self.server = server
        self.session = session
        self.actions = actions
        robot = scene.robot
        gui = server.gui
        self.part = gui.add_dropdown("Moving part", [TOOL] + [f"J{i}" for i in range(1, robot.dof + 1)], initial_value=TOOL)
        self.frame = gui.add_dropdown("Frame", list(FRAME_NAMES), initial_value="world")
        self._directions = {direction_label(c): c for c in (*AXES, *PLANES)}
        self.constraint = gui.add_dropdown("Direction", list(self._directions), initial_value=direction_label("xy"))
        self.motion = gui.add_dropdown("Motion", list(MOTIONS), initial_value="translate")
        # the session's one flag, shown here and on the Program tab ("Automatic generation")
        self.generate = gui.add_checkbox("Generate statements", initial_value=session.program.view().auto_generate,
                                         hint="write the motion you drive as program statements, in the chosen frame")
        self._setting = False
        self.generate.on_update(self._on_generate)
        self.written = gui.add_markdown("")  # the statements the drags wrote last (``written_markdown``)
        self.status = gui.add_markdown("")
        self.collision = gui.add_markdown("")
        with gui.add_folder("Joints (deg)"):
            self.sliders: list[viser.GuiInputHandle[float]] = []
            for i in range(robot.dof):
                slider = gui.add_slider(
                    f"J{i + 1}", min=float(np.degrees(robot.lower[i])), max=float(np.degrees(robot.upper[i])),
                    step=0.1, initial_value=0.0,
                )
                slider.on_update(self._slider_callback(i + 1))
                self.sliders.append(slider)
        with gui.add_folder("Frames", expand_by_default=False):
            for name in FRAME_AXES:
                box = gui.add_checkbox(f"Show {name}", initial_value=False)
                box.on_update(lambda event, name=name: scene.set_axes_visible(name, bool(event.target.value)))
        self.drive_gizmo = DriveGizmo(server, session, actions, self._choice)
        self.gizmo = self.drive_gizmo.handle
        self._timer_lock = threading.Lock()
        self._release_timer: threading.Timer | None = None
        for control in (self.part, self.frame, self.motion, self.constraint):
            control.on_update(lambda _: self.drive_gizmo.refresh())
        self.drive_gizmo.refresh()

    def _choice(self) -> tuple[int | None, str, str, str]:
        """(joint number or ``None`` for the tool, frame, constraint, motion) as chosen."""
        part = self.part.value
        joint = None if part == TOOL else int(part[1:])
        return joint, self.frame.value, self._directions[self.constraint.value], self.motion.value

    # -- callbacks ---------------------------------------------------------------------------
    def _slider_callback(self, joint: int):
        def callback(event: viser.GuiEvent) -> None:
            if event.client is None:  # our own programmatic update
                return
            value = float(np.radians(event.target.value))
            self.actions.run(f"turn J{joint}", lambda: self.session.arm.set_joint(joint, value))
            self.server.flush()  # as for the gizmo: the new pose goes out now, not at the window's end
            self._release_soon()

        return callback

    def _release_soon(self) -> None:
        """A slider has no "let go" event: treat a pause of ``SLIDER_RELEASE_S`` as one."""
        with self._timer_lock:
            if self._release_timer is not None:
                self._release_timer.cancel()
            self._release_timer = threading.Timer(SLIDER_RELEASE_S, lambda: self.actions.run("release", self.session.arm.release))
            self._release_timer.daemon = True
            self._release_timer.start()

    def _on_generate(self, event: viser.GuiEvent) -> None:
        if self._setting or event.client is None:
            return
        on = bool(self.generate.value)
        self.actions.run("automatic generation", lambda: self.session.program.set_auto_generate(on))

    # -- session events -----------------------------------------------------------------------
    def show_arm(self, arm: ArmView) -> None:
        for slider, value in zip(self.sliders, arm.q_deg):
            rounded = float(round(value, 1))
            if slider.value != rounded:
                slider.value = rounded
        self.drive_gizmo.snap(arm)
        x, y, z = arm.tool_xyz_mm
        text = f"Tool (world): x {x:.1f} mm, y {y:.1f} mm, z {z:.1f} mm"
        if arm.held:
            text += f"; holding {arm.held}"
        if arm.blocked:
            text += f"  \n**Blocked ({arm.blocked}):** {arm.message}"
        self.status.content = text

    def show_program(self, view: ProgramView) -> None:
        written = written_markdown(view)
        if self.written.content != written:
            self.written.content = written
        if self.generate.value != view.auto_generate:
            self._setting = True
            try:
                self.generate.value = view.auto_generate
            finally:
                self._setting = False

    def show_collision(self, view: CollisionView) -> None:
        lines = []
        if view.colliding:
            pairs = ", ".join(f"{a} / {b}" for a, b in view.pairs[:4])
            lines.append(f"**COLLISION:** {pairs}")
        if view.joint_limit:
            lines.append(f"**Joint limit:** {view.joint_limit}")
        if view.min_distance is not None and view.nearest is not None and not view.colliding:
            # the object (or the ground) the tool is nearest; the arm's own links never count
            lines.append(f"Nearest: {view.nearest[1]} at {view.min_distance * 1e3:.1f} mm")
        if view.zone_object is not None and view.zone_distance is not None:
            lines.append(f"Zone: {view.zone.value} ({view.zone_object} at {view.zone_distance * 1e3:.0f} mm)")
        self.collision.content = "  \n".join(lines)
