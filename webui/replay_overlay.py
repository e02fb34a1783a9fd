"""Side by side in the replay: a submitted range as the console planned it and as the robot
reported it, with the largest gap between them at the same time drawn and labelled.

The geometry (planned and reported tool points, the worst pair) comes from
``server.replay.comparison``; this only draws it.
"""

from __future__ import annotations

import numpy as np
import viser

from server.replay.comparison import RangeComparison
from webui.ghost import GHOST_COLOR

PLAN_COLOR = (40, 110, 255)  # blue: what the console said would happen
REPORTED_COLOR = GHOST_COLOR  # the ghost's green: what the robot said happened
GAP_COLOR = (230, 0, 120)


def _polyline(server: viser.ViserServer, name: str, points: np.ndarray, color, thickness: float):
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) < 2:
        return None
    segments = np.stack([points[:-1], points[1:]], axis=1)
    return server.scene.add_line_segments(name, segments, color, thickness=thickness, thickness_units="screen")


class SideBySide:
    """The planned path, the reported path, and the largest gap of one range."""

    ROOT = "/side_by_side"

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self._handles: list = []
        self.shown: int | None = None

    def clear(self) -> None:
        for handle in self._handles:
            handle.remove()
        self._handles = []
        self.shown = None

    def show(self, comparison: RangeComparison | None) -> None:
        self.clear()
        if comparison is None:
            return
        s = self.server.scene
        with self.server.atomic():
            for handle in (
                _polyline(self.server, f"{self.ROOT}/planned", comparison.planned_world_p_tool, PLAN_COLOR, 4.0),
                _polyline(self.server, f"{self.ROOT}/reported", comparison.reported_world_p_tool, REPORTED_COLOR, 2.5),
            ):
                if handle is not None:
                    self._handles.append(handle)
            if comparison.largest_gap_points is not None:
                planned, reported = comparison.largest_gap_points
                self._handles.append(s.add_line_segments(
                    f"{self.ROOT}/gap", np.stack([planned, reported])[None], GAP_COLOR, thickness=5.0,
                    thickness_units="screen"))
                self._handles.append(s.add_label(
                    f"{self.ROOT}/gap_label",
                    f"largest gap {1e3 * comparison.largest_gap_m:.1f} mm at {comparison.largest_gap_at_s:.2f} s",
                    position=tuple(reported), anchor="bottom-left"))
        self.shown = comparison.index
