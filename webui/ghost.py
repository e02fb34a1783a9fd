"""The remote arm as a translucent ghost, drawn from the newest telemetry frame.

Why a ghost: across seconds of delay the operator must see at once what is commanded (the solid
virtual arm) and what was last reported (the ghost), and how old that report is. The label says
"remote arm as of 3.1 s ago" so nobody mistakes an old picture for the present. The link poses
come from the robot model's own forward kinematics, exactly as for the virtual arm.
"""

from __future__ import annotations

import numpy as np
import viser

from shared.robots.model import Robot
from shared.robots.shapes import link_meshes
from webui.scene_util import place

# green, far from the virtual arm's greys and from the path's orange and the collision red (the
# pale blue it had read as the solid arm's grey through 35 % opacity); the legend names it
GHOST_COLOR = (20, 190, 110)
GHOST_OPACITY = 0.4


def age_text(age_s: float | None) -> str:
    """How old a report is, in words the operator reads at a glance."""
    if age_s is None:
        return "no telemetry yet"
    if age_s < 0.05:
        return "as of now"
    if age_s < 60.0:
        return f"as of {age_s:.1f} s ago"
    return f"as of {age_s / 60.0:.0f} min ago"


class RemoteGhost:
    """Translucent copy of the arm at the reported joint vector, with an age label at the tool."""

    def __init__(self, server: viser.ViserServer, robot: Robot, world_T_base: np.ndarray) -> None:
        self.server = server
        self.robot = robot
        self.world_T_base = np.asarray(world_T_base, dtype=float)
        self._data = robot.new_data()
        self._links: list[viser.FrameHandle] = []
        for i in range(robot.dof + 1):
            node = server.scene.add_frame(f"/ghost/link{i}", show_axes=False, visible=False)
            mesh = link_meshes(robot.shapes.get(i, ()))
            if mesh is not None:
                server.scene.add_mesh_simple(
                    f"/ghost/link{i}/mesh", mesh.vertices, mesh.faces, color=GHOST_COLOR,
                    opacity=GHOST_OPACITY, cast_shadow=False, receive_shadow=False,
                )
            self._links.append(node)
        # the age label rides on the ghost's shoulder (link 1), clear of the tool and its gizmo
        self.label = server.scene.add_label("/ghost/link1/age", "remote arm: no telemetry yet",
                                            visible=False, anchor="bottom-left", position=(0.0, 0.0, 0.0))
        self.visible = False
        self._drawn_q: np.ndarray | None = None  # the joint vector the links were last placed at
        self._drawn_text = ""

    def show(self, q: np.ndarray | None, age_s: float | None, what: str = "") -> None:
        """Pose the ghost at ``q`` (rad) and label it with the report's age; ``q`` None hides it."""
        if q is None:
            self.hide()
            return
        q = np.array(q, dtype=float)
        text = f"remote arm {age_text(age_s)}"
        if what:
            text += f" ({what})"
        if self.visible and self._drawn_q is not None and np.array_equal(q, self._drawn_q):
            # telemetry at 50 Hz mostly repeats a resting arm: no forward kinematics and no node
            # updates for every client then, only the label when its text changed
            if text != self._drawn_text:
                self.label.text = text
                self._drawn_text = text
            return
        world_T_links = self.world_T_base @ self.robot.link_poses(q, self._data)
        with self.server.atomic():
            for node, world_T_link in zip(self._links, world_T_links):
                place(node, world_T_link)
                node.visible = True
            self.label.text = text
            self.label.visible = True
        self.visible = True
        self._drawn_q, self._drawn_text = q, text

    def hide(self) -> None:
        self._drawn_q = None
        if not self.visible:
            return
        with self.server.atomic():
            for node in self._links:
                node.visible = False
            self.label.visible = False
        self.visible = False
