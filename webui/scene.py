"""The 3D scene of the console: the cell's objects, the virtual arm, frames on demand.

Draws what the session says; holds no kinematics of its own (link poses come from the robot
model). Meshes are built once; only node poses change when the arm moves (stable node names,
handles updated in place). Each collision body (``link3``, ``peg``) has a scene node whose
frame is the body's own frame, so overlays such as red triangles can hang under it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import viser

from shared.cells.cell import Cell
from shared.collision.mesh_model import BodyMesh, body_mesh
from shared.robots.shapes import link_meshes
from shared.terrain.cell import TERRAIN_OBJECT
from webui.scene_util import colored, height_shaded, place

FRAME_AXES = ("world", "base", "work", "tool")


def arm_colour(robot) -> tuple[int, int, int]:
    """The colour the virtual arm is drawn in: its robot file's colour of most of its links
    (the legend shows it next to the ghost's)."""
    colours = [tuple(shapes[0].color) for shapes in robot.shapes.values() if shapes]
    if not colours:
        return (200, 200, 200)
    return max(set(colours), key=colours.count)


class CellScene:
    """The cell and the virtual arm in a viser scene."""

    def __init__(self, server: viser.ViserServer, cell: Cell) -> None:
        self.server = server
        self.cell = cell
        self.robot = cell.robot
        self._data = self.robot.new_data()  # the scene's own pinocchio data (model vs data)
        server.scene.set_up_direction("+z")
        # no shadow maps: each light re-renders the scene for them in every frame. Measured in
        # headless Chromium (software WebGL) while dragging: 1.4 -> 2.8 drawn frames/s.
        server.scene.configure_default_lights(enabled=True, cast_shadow=False)
        # No environment map either: its image-based lighting is most of a frame's cost where the
        # page draws in software (a console opened on a machine without a GPU, which viser warns
        # of, and headless Chromium): the page's idle redraw (viser's 1 s heartbeat) took 0.38 of
        # a core with it and 0.20 without, in the same minutes. A sky light and a key and a fill
        # light from two sides light every face of the cell instead; with the default lights
        # alone the sides turned black.
        server.scene.configure_environment_map(None)
        server.scene.add_light_hemisphere("/lights/sky", sky_color=(255, 255, 255), ground_color=(120, 110, 100),
                                          intensity=1.2)
        server.scene.add_light_directional("/lights/key", intensity=2.2, position=(1.5, -2.5, 3.0))
        server.scene.add_light_directional("/lights/fill", intensity=0.9, position=(-2.0, 1.5, 1.0))
        server.scene.add_grid("/floor", width=3.0, height=3.0, cell_size=0.1, position=(0.0, 0.0, 0.0))
        self.body_nodes: dict[str, str] = {}
        self.body_meshes: dict[str, BodyMesh] = {}
        self._objects: dict[str, viser.FrameHandle] = {}
        self._object_home = {obj.name: obj.world_T_object for obj in cell.objects}
        self._object_shown: dict[str, np.ndarray] = {}
        for obj in cell.objects:
            node = server.scene.add_frame(f"/cell/{obj.name}", show_axes=False)
            place(node, obj.world_T_object)
            mesh = link_meshes(obj.shapes)
            if mesh is not None:
                # a terrain shaded by height (its relief, and apart from the grid); the rest in its colour
                drawn = height_shaded(mesh, obj.world_T_object) if obj.name == TERRAIN_OBJECT else colored(mesh, obj.color)
                server.scene.add_mesh_trimesh(f"/cell/{obj.name}/mesh", drawn)
            self._register_body(obj.name, f"/cell/{obj.name}", obj.shapes)
            self._objects[obj.name] = node
            self._object_shown[obj.name] = obj.world_T_object
        self._links: list[viser.FrameHandle] = []
        for i in range(self.robot.dof + 1):
            node = server.scene.add_frame(f"/robot/link{i}", show_axes=False, axes_length=0.08, axes_radius=0.004)
            shapes = self.robot.shapes.get(i, ())
            mesh = link_meshes(shapes)
            if mesh is not None:
                server.scene.add_mesh_trimesh(f"/robot/link{i}/mesh", colored(mesh, shapes[0].color))
            self._register_body(f"link{i}", f"/robot/link{i}", shapes)
            self._links.append(node)
        # the tool point rides on the last link: the scene graph places it, no maths here
        self.tcp_node = f"/robot/link{self.robot.dof}/tcp"
        place(server.scene.add_frame(self.tcp_node, show_axes=False), cell.flange_T_tcp)
        self._axes: dict[str, viser.FrameHandle] = {
            name: server.scene.add_frame(
                f"{self.tcp_node}/axes" if name == "tool" else f"/axes/{name}",
                axes_length=0.15, axes_radius=0.006, visible=False,
            )
            for name in FRAME_AXES
        }
        place(self._axes["world"], np.eye(4))
        place(self._axes["base"], cell.world_T_base)
        place(self._axes["work"], cell.frame("work"))

    def _register_body(self, name: str, node: str, shapes) -> None:
        mesh = body_mesh(name, shapes)
        if mesh is not None:
            self.body_nodes[name] = node
            self.body_meshes[name] = mesh

    def set_axes_visible(self, name: str, visible: bool) -> None:
        self._axes[name].visible = visible

    def show_arm(self, q: np.ndarray) -> None:
        """Pose every link for joint vector ``q`` (rad), from the robot model's link poses."""
        world_T_links = self.cell.world_T_base @ self.robot.link_poses(np.asarray(q, dtype=float), self._data)
        with self.server.atomic():
            for node, world_T_link in zip(self._links, world_T_links):
                place(node, world_T_link)

    def show_objects(self, world_T_objects: Mapping[str, np.ndarray]) -> None:
        """Put objects at the given poses; objects not named go back to the cell file's pose."""
        with self.server.atomic():
            for name, node in self._objects.items():
                pose = np.asarray(world_T_objects.get(name, self._object_home[name]), dtype=float)
                if not np.array_equal(pose, self._object_shown[name]):
                    place(node, pose)
                    self._object_shown[name] = pose

    def set_arm_visible(self, visible: bool) -> None:
        for node in self._links:
            node.visible = visible
