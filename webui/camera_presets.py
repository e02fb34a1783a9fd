"""The view's camera presets, per page: Front (the default), Side, Top, Follow tool.

The views come from the cell (``shared.cells.framing.cell_views``: the default looks across the
task's objects from above, the others about the same focus); this module only puts a page's
camera where its operator asked. Every page keeps its own camera: a preset moves the camera of
the page whose button was pressed (viser's per-client handle), never another's. "Follow tool"
looks at the virtual arm's tool and then moves that page's camera with the tool, keeping the
operator's own orbit about it, until another preset is pressed.
"""

from __future__ import annotations

import logging
import threading

import numpy as np
import viser

from shared.cells.framing import CellViews, ViewPose

log = logging.getLogger(__name__)

#: button text -> preset of ``CellViews``
LABELS = {"Front": "front", "Side": "side", "Top": "top", "Follow tool": "follow"}
UP = (0.0, 0.0, 1.0)


def aim(client: viser.ClientHandle, pose: ViewPose) -> None:
    """Put one page's camera at ``pose`` (its look-at point last: viser moves it with the
    position)."""
    camera = client.camera
    with client.atomic():
        camera.fov = float(pose.fov)  # the top view's is narrow; every other view has the page's usual one
        camera.up_direction = UP
        camera.position = tuple(pose.position)
        camera.look_at = tuple(pose.look_at)


class CameraPresets:
    """A row of preset buttons; which pages follow the tool."""

    def __init__(self, server: viser.ViserServer, views: CellViews) -> None:
        self.server = server
        self.views = views
        self._lock = threading.Lock()  # the state below
        self._aiming = threading.Lock()  # one camera move at a time: a press never lands under a follow
        self._tool = np.asarray(views.focus.tool, dtype=float)
        self._following: dict[int, viser.ClientHandle] = {}
        self.buttons = server.gui.add_button_group(
            "View", list(LABELS), hint="this page's camera: the work from the front (the default), from the side, "
                                       "from above, or following the tool")
        self.buttons.on_click(self._on_click)
        server.on_client_disconnect(self._forget)

    def set_initial(self) -> None:
        """The camera a new page opens with (and viser's Reset View): the front view."""
        front = self.views.front
        self.server.initial_camera.look_at = tuple(front.look_at)
        self.server.initial_camera.position = tuple(front.position)

    def following(self, client_id: int) -> bool:
        with self._lock:
            return client_id in self._following

    # -- the buttons ------------------------------------------------------------------------------
    def _on_click(self, event: viser.GuiEvent) -> None:
        client = event.client
        if client is None:
            return
        self.press(client, LABELS[event.target.value])

    def press(self, client: viser.ClientHandle, preset: str) -> None:
        """What a page's button does: ``preset`` (``front``, ``side``, ``top``, ``follow``)."""
        with self._aiming:
            with self._lock:
                tool = self._tool.copy()
                if preset == "follow":
                    self._following[client.client_id] = client
                else:
                    self._following.pop(client.client_id, None)
            try:
                aim(client, self.views.preset(preset, tool))
            except (AssertionError, ValueError):  # the page has not reported its camera yet
                log.warning("camera preset %s: page %s has no camera yet", preset, client.client_id)

    def _forget(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._following.pop(client.client_id, None)

    # -- the tool moved ---------------------------------------------------------------------------
    def follow(self, world_T_tcp) -> None:
        """The virtual arm's tool stands at ``world_T_tcp`` (4x4): the cameras of the pages that
        follow it move with it, each keeping its own direction and distance."""
        tool = np.asarray(world_T_tcp, dtype=float)[:3, 3]
        with self._lock:
            if np.array_equal(tool, self._tool):
                return
            self._tool = tool
            if not self._following:
                return
        with self._aiming:
            with self._lock:
                clients = list(self._following.values())
            for client in clients:
                try:
                    camera = client.camera
                    offset = np.asarray(camera.position) - np.asarray(camera.look_at)
                    aim(client, ViewPose(tool + offset, tool.copy(), self.views.front.fov))
                except (AssertionError, ValueError):
                    continue  # no camera yet, or a degenerate one: the next move tries again
                except Exception:  # noqa: BLE001 - a page that just went away: never fail the arm's drawing
                    log.debug("follow camera: page %s", client.client_id, exc_info=True)
