"""The Drive tab's transform gizmo: on the tool, the handles the jog choice allows, drawn with the
chosen frame's axes; on a joint, one ring about the joint's axis that turns it.

Which handles, where they stand and what a drag asks of the arm come from
``shared.robots.handles`` (for the arm as the last ``ArmView`` shows it, so drawing takes no
session lock) and the session (``session.arm.drag_tool_handle`` / ``turn_joint_to_handle``); this
module only places the gizmo and turns its drags into session calls. The gizmo draws over the arm
(``depth_test=False``) so no handle hides under the gripper. viser offers no way to keep a press
that misses every handle from turning the camera: a larger gizmo drawn on top makes misses rarer.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np
import viser

from server.console import ArmView, Session
from shared.robots.handles import (
    JOINT_HANDLES,
    HandleChoice,
    joint_handle,
    tool_handle,
    tool_handles,
)
from webui.actions import Actions
from webui.scene_util import matrix, wxyz

log = logging.getLogger(__name__)

GIZMO_SCALE = 0.24  # m: arrows and rings long enough to grab from the default view
GIZMO_LINE_WIDTH = 4.0


class DriveGizmo:
    """The gizmo and its drags. ``choice()`` gives (moving part, frame, constraint, motion) as
    the Drive tab shows them; the part is ``None`` for the tool or a joint number."""

    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions,
                 choice: Callable[[], tuple[int | None, str, str, str]]) -> None:
        self.server = server
        self.session = session
        self.actions = actions
        self._choice = choice
        self.handle = server.scene.add_transform_controls(
            "/tool_gizmo", scale=GIZMO_SCALE, line_width=GIZMO_LINE_WIDTH, depth_test=False,
        )
        self._grip = np.eye(4)
        self._dragging = False
        self._arm: ArmView = session.arm.view()
        self.offered: HandleChoice | None = None
        self.handle.on_update(self._on_update)

    # -- what is offered ------------------------------------------------------------------------
    def refresh(self) -> None:
        """Offer the handles of the current choice and stand the gizmo where they act."""
        joint, _frame, constraint, motion = self._choice()
        offered = JOINT_HANDLES if joint is not None else tool_handles(constraint, motion)
        if offered != self.offered:
            h = self.handle
            h.active_axes = offered.active_axes
            h.disable_axes = not offered.arrows
            h.disable_sliders = not offered.planes
            h.disable_rotations = not offered.rings
            self.offered = offered
        self.snap()

    def snap(self, arm: ArmView | None = None) -> None:
        """Stand the gizmo on the arm as ``arm`` (or the last view) shows it, not while the
        operator holds it."""
        if arm is not None:
            self._arm = arm
        if self._dragging:
            return
        joint, frame, _constraint, _motion = self._choice()
        if joint is not None:
            pose = joint_handle(self.session.robot, np.asarray(self._arm.q), joint, self.session.cell.world_T_base)
        else:
            tool = tool_handle(frame, self.session.frames, np.asarray(self._arm.world_T_tcp))
            pose, self._grip = tool.world_T_handle, tool.handle_T_tcp
        self.handle.wxyz = wxyz(pose)
        self.handle.position = pose[:3, 3]

    # -- drags ----------------------------------------------------------------------------------
    def _on_update(self, event) -> None:
        phase = getattr(event, "phase", "update")
        if phase == "start":
            self._dragging = True
            return
        if phase == "end":
            self._dragging = False
            self.actions.run("release", self.session.arm.release)
            self.snap()
            return
        joint, frame, constraint, motion = self._choice()
        goal = matrix(self.handle.wxyz, self.handle.position)
        if joint is not None:
            self.actions.run(f"turn J{joint}", lambda: self.session.arm.turn_joint_to_handle(joint, goal))
        else:
            grip = self._grip
            self.actions.run(
                "drive",
                lambda: self.session.arm.drag_tool_handle(goal, grip, frame=frame, constraint=constraint, motion=motion),
            )
        # the session's events have redrawn the arm by now: send them at once rather than at the
        # end of viser's window (up to 1/60 s), which was most of a drag update's round trip
        self.server.flush()
