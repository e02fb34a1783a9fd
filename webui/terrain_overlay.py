"""What a rover-cell operator sees over the terrain (seed 004): the minimum-distance segment
between arm and ground, the virtual sensors (green clear, red colliding), the triangles touching
the arm in red, and the picked target with its surface normal.

Draws the session's :class:`TerrainView` and :class:`PlacementView` as they are: every point is
computed by ``shared.terrain`` on the server.
"""

from __future__ import annotations

import numpy as np
import viser

from server.console import PlacementView, TerrainView

SEGMENT_COLOR = (255, 200, 0)
SENSOR_CLEAR = (60, 200, 90)
SENSOR_HIT = (255, 0, 0)
CONTACT_COLOR = (255, 0, 0)
TARGET_COLOR = (0, 170, 255)
NORMAL_LENGTH = 0.08  # m
CONTACT_LIFT = 0.0005  # m: red paint just above the ground so it wins the depth test


class TerrainOverlay:
    ROOT = "/terrain_overlay"

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self._segment: viser.LineSegmentsHandle | None = None
        self._sensors: viser.LineSegmentsHandle | None = None
        self._contacts: viser.MeshHandle | None = None
        self._target: list[viser.SceneNodeHandle] = []
        self._corners_shown: list = []

    # -- arm against ground ------------------------------------------------------------------
    def show(self, view: TerrainView | None, visible: bool = True) -> None:
        """Redraw for ``view``; ``visible=False`` hides the arm-dependent parts (the arm drawn
        is not the virtual arm: a preview or telepresence)."""
        with self.server.atomic():
            self._draw_segment(view if visible else None)
            self._draw_sensors(view if visible else None)
            self._draw_contacts(view if visible else None)

    def _draw_segment(self, view: TerrainView | None) -> None:
        if view is None or view.in_collision or not np.isfinite(view.distance):
            if self._segment is not None:
                self._segment.visible = False
            return
        points = np.array([[view.world_p_arm, view.world_p_terrain]], dtype=np.float32)
        if self._segment is None:
            self._segment = self.server.scene.add_line_segments(
                f"{self.ROOT}/min_distance", points, SEGMENT_COLOR, thickness=3.0, thickness_units="screen")
        else:
            self._segment.points = points
        self._segment.visible = True

    def _draw_sensors(self, view: TerrainView | None) -> None:
        sensors = view.sensors if view is not None else None
        if sensors is None or not sensors.starts:
            if self._sensors is not None:
                self._sensors.remove()
                self._sensors = None
            return
        points = np.stack([np.asarray(sensors.starts), np.asarray(sensors.ends)], axis=1).astype(np.float32)
        colors = np.where(np.asarray(sensors.collides)[:, None, None], np.array(SENSOR_HIT), np.array(SENSOR_CLEAR))
        colors = np.broadcast_to(colors, points.shape).astype(np.uint8)
        if self._sensors is None or len(self._sensors.points) != len(points):
            if self._sensors is not None:
                self._sensors.remove()
            self._sensors = self.server.scene.add_line_segments(f"{self.ROOT}/sensors", points, colors, thickness=1.5, thickness_units="screen")
        else:
            self._sensors.points = points
            self._sensors.colors = colors

    def _draw_contacts(self, view: TerrainView | None) -> None:
        corners = view.contact_corners if view is not None else []
        if corners == self._corners_shown:
            return  # the same triangles: nothing to send again
        self._corners_shown = corners
        if self._contacts is not None:
            self._contacts.remove()
            self._contacts = None
        if not corners:
            return
        vertices = np.asarray(corners, dtype=np.float32).reshape(-1, 3) + np.array([0.0, 0.0, CONTACT_LIFT], np.float32)
        faces = np.arange(len(vertices), dtype=np.uint32).reshape(-1, 3)
        self._contacts = self.server.scene.add_mesh_simple(
            f"{self.ROOT}/contacts", vertices, faces, color=CONTACT_COLOR, side="double", cast_shadow=False, receive_shadow=False)

    # -- the picked target -------------------------------------------------------------------
    def show_target(self, placement: PlacementView | None) -> None:
        for node in self._target:
            node.remove()
        self._target = []
        if placement is None:
            return
        p = np.asarray(placement.world_p_target, dtype=float)
        n = np.asarray(placement.world_n_surface, dtype=float)
        scene = self.server.scene
        self._target = [
            scene.add_icosphere(f"{self.ROOT}/target", radius=0.008, color=TARGET_COLOR, position=tuple(p)),
            scene.add_line_segments(f"{self.ROOT}/target_normal", np.array([[p, p + NORMAL_LENGTH * n]], dtype=np.float32),
                                    TARGET_COLOR, thickness=3.0, thickness_units="screen"),
        ]
