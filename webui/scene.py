"""The 3D scene of the console: the cell's objects, the virtual arm, frames on demand.

Draws what the session says; holds no kinematics. Meshes are built once; only the link frames'
poses change when the arm moves (stable node names, handles updated in place).
"""

from __future__ import annotations

import numpy as np
import trimesh
import viser
import viser.transforms as vtf

from server.session import Session, VirtualState
from shared.robots.shapes import link_meshes

FRAME_AXES = ("world", "base", "work", "tool")


def _wxyz(transform: np.ndarray) -> np.ndarray:
    return vtf.SO3.from_matrix(transform[:3, :3]).wxyz


def _place(handle: viser.SceneNodeHandle, transform: np.ndarray) -> None:
    handle.wxyz = _wxyz(transform)
    handle.position = transform[:3, 3]


def _colored(mesh: trimesh.Trimesh, color: tuple[int, int, int]) -> trimesh.Trimesh:
    out = mesh.copy()
    out.visual = trimesh.visual.ColorVisuals(out, face_colors=np.array([*color, 255], dtype=np.uint8))
    return out


class CellScene:
    """The cell and the virtual arm in a viser scene, following a ``Session``."""

    def __init__(self, server: viser.ViserServer, session: Session) -> None:
        self.server = server
        self.session = session
        cell = session.cell
        server.scene.set_up_direction("+z")
        server.scene.add_grid("/floor", width=3.0, height=3.0, cell_size=0.1, position=(0.0, 0.0, 0.0))
        for obj in cell.objects:
            node = server.scene.add_frame(f"/cell/{obj.name}", show_axes=False)
            _place(node, obj.world_T_object)
            mesh = link_meshes(obj.shapes)
            if mesh is not None:
                server.scene.add_mesh_trimesh(f"/cell/{obj.name}/mesh", _colored(mesh, obj.color))
        self._links: list[viser.FrameHandle] = []
        robot = session.robot
        for i in range(robot.dof + 1):
            node = server.scene.add_frame(f"/robot/link{i}", show_axes=False, axes_length=0.08, axes_radius=0.004)
            shapes = robot.shapes.get(i, ())
            mesh = link_meshes(shapes)
            if mesh is not None:
                color = shapes[0].color
                server.scene.add_mesh_trimesh(f"/robot/link{i}/mesh", _colored(mesh, color))
            self._links.append(node)
        self._axes: dict[str, viser.FrameHandle] = {
            name: server.scene.add_frame(f"/axes/{name}", axes_length=0.15, axes_radius=0.006, visible=False)
            for name in FRAME_AXES
        }
        _place(self._axes["world"], np.eye(4))
        _place(self._axes["base"], cell.world_T_base)
        _place(self._axes["work"], cell.frame("work"))
        self.show(session.state)
        session.subscribe(self.show)

    def set_axes_visible(self, name: str, visible: bool) -> None:
        self._axes[name].visible = visible

    def show(self, state: VirtualState) -> None:
        """Pose every link for the state's joint vector."""
        world_T_links = self.session.cell.world_T_base @ self.session.robot.link_poses(state.q, self._data)
        with self.server.atomic():
            for node, world_T_link in zip(self._links, world_T_links):
                _place(node, world_T_link)
            _place(self._axes["tool"], state.world_T_tcp)

    @property
    def _data(self):  # the scene's own pinocchio data (model vs data)
        data = getattr(self, "_pin_data", None)
        if data is None:
            data = self._pin_data = self.session.robot.new_data()
        return data
