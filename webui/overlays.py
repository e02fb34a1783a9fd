"""Synthetic aids drawn over the cell (thesis 2.4.1, 4.3.2): the predicted tool path of
statements sent but not yet done, interfering triangles in red with a warning, the control zone.

Each overlay owns a few stable scene nodes and redraws them from what the session reports; the
geometry (tool points, triangle corners in the world) is computed by the server's shared core.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import viser

from shared.collision.mesh_model import BodyMesh

PATH_COLOR = (255, 160, 0)
HIT_COLOR = (255, 0, 0)


class PredictedPath:
    """A polyline through the tool positions the robot is predicted to pass (world, m)."""

    NAME = "/predicted_path"

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self._handle: viser.LineSegmentsHandle | None = None
        self._points: np.ndarray | None = None

    def show(self, world_p_tool: np.ndarray | None) -> None:
        points = None if world_p_tool is None else np.asarray(world_p_tool, dtype=float).reshape(-1, 3)
        if points is None or len(points) < 2:
            if self._handle is not None:
                self._handle.remove()
                self._handle = None
            self._points = None
            return
        if self._points is not None and self._points.shape == points.shape and np.allclose(self._points, points):
            return
        segments = np.stack([points[:-1], points[1:]], axis=1)
        self._handle = self.server.scene.add_line_segments(
            self.NAME, segments, PATH_COLOR, thickness=3.0, thickness_units="screen"
        )
        self._points = points


class CollisionOverlay:
    """Interfering triangles painted red and a warning label naming the colliding bodies.

    The session reports triangle ids per collision body (``link3``, ``peg``); each red mesh is a
    child of that body's scene node, so it holds the body's own-frame corners (the same mesh
    the collision core tests, from ``body_mesh``) and the scene graph places it.
    """

    def __init__(
        self, server: viser.ViserServer, body_meshes: Mapping[str, BodyMesh], body_nodes: Mapping[str, str], tcp_node: str
    ) -> None:
        self.server = server
        self.body_meshes = dict(body_meshes)
        self.body_nodes = dict(body_nodes)
        self._meshes: dict[str, viser.MeshHandle] = {}
        self._shown: dict[str, tuple[int, ...]] = {}
        # the warning hangs just below the tool point, wherever the arm is drawn
        self.label = server.scene.add_label(f"{tcp_node}/collision_label", "", visible=False, anchor="top-left",
                                            position=(0.0, 0.0, 0.04))

    def show(self, triangles: Mapping[str, Sequence[int]], warning: str) -> None:
        wanted = {body: tuple(ids) for body, ids in triangles.items() if ids and body in self.body_meshes}
        for body in list(self._meshes):
            if body not in wanted:
                self._meshes.pop(body).remove()
                self._shown.pop(body, None)
        for body, ids in wanted.items():
            if self._shown.get(body) == ids:
                continue
            corners = self.body_meshes[body].triangles[np.asarray(ids, dtype=np.int64)]
            vertices = corners.reshape(-1, 3)
            faces = np.arange(len(vertices), dtype=np.uint32).reshape(-1, 3)
            # slightly enlarged about the body origin so the red paint wins the depth test
            self._meshes[body] = self.server.scene.add_mesh_simple(
                f"{self.body_nodes[body]}/collision", vertices, faces, color=HIT_COLOR, side="double",
                scale=1.002, cast_shadow=False, receive_shadow=False,
            )
            self._shown[body] = ids
        if warning:
            self.label.text = f"COLLISION: {warning}"
            self.label.visible = True
        else:
            self.label.visible = False

    @property
    def triangle_count(self) -> int:
        return sum(len(ids) for ids in self._shown.values())
