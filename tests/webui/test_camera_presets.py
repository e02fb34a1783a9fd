"""The view's presets (``webui.camera_presets``) move the camera of the page that asked, and only
that one; "Follow tool" moves a page's camera with the virtual arm's tool. Pages are stand-ins
with viser's camera handle's setters (a position setter that carries the look-at point along, as
viser's does); the real page is tests/browser/test_camera_presets_page.py."""

from __future__ import annotations

from contextlib import nullcontext

import numpy as np
import pytest
import viser

from server.console import Session
from shared.cells.framing import cell_views
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.paths import ASSETS_DIR
from support import free_port
from webui.camera_presets import CameraPresets
from webui.console import build_console


class FakeCamera:
    def __init__(self, position, look_at) -> None:
        self._position = np.asarray(position, dtype=float)
        self.look_at = np.asarray(look_at, dtype=float)
        self.up_direction = np.array([0.0, 0.0, 1.0])
        self.fov = np.radians(75.0)

    @property
    def position(self) -> np.ndarray:
        return self._position

    @position.setter
    def position(self, value) -> None:  # viser moves the look-at point with the camera
        value = np.asarray(value, dtype=float)
        self.look_at = self.look_at + (value - self._position)
        self._position = value


class FakeClient:
    def __init__(self, client_id: int, camera: FakeCamera) -> None:
        self.client_id = client_id
        self.camera = camera

    def atomic(self):
        return nullcontext()


@pytest.fixture(scope="module")
def peg_console():
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    session = Session(load_cell(DEFAULT_CELL))
    console = build_console(server, session)
    yield server, session, console
    session.close()
    server.stop()


def test_a_new_page_opens_at_the_cells_front_view(peg_console) -> None:
    server, session, console = peg_console
    front = cell_views(session.cell).front
    np.testing.assert_allclose(server.initial_camera.position, front.position)
    np.testing.assert_allclose(server.initial_camera.look_at, front.look_at)
    assert console.views is not None
    assert list(console.views.buttons.options) == ["Front", "Side", "Top", "Follow tool"]


def test_a_preset_moves_only_the_page_that_pressed_it(peg_console) -> None:
    _, session, console = peg_console
    views = console.views.views
    front = views.front
    a = FakeClient(1, FakeCamera(front.position, front.look_at))
    b = FakeClient(2, FakeCamera(front.position, front.look_at))
    for preset in ("top", "side", "front"):
        console.views.press(a, preset)
        np.testing.assert_allclose(a.camera.position, views.preset(preset).position)
        np.testing.assert_allclose(a.camera.look_at, views.preset(preset).look_at)
        np.testing.assert_allclose(b.camera.position, front.position)
        np.testing.assert_allclose(b.camera.look_at, front.look_at)


def test_follow_tool_moves_the_following_page_with_the_tool(peg_console) -> None:
    _, session, console = peg_console
    views = console.views
    front = views.views.front
    a = FakeClient(11, FakeCamera(front.position, front.look_at))
    b = FakeClient(12, FakeCamera(front.position, front.look_at))
    tool = np.asarray(session.arm.view().world_T_tcp)[:3, 3]
    views.press(a, "follow")
    assert views.following(11) and not views.following(12)
    np.testing.assert_allclose(a.camera.look_at, tool)
    np.testing.assert_allclose(a.camera.position, tool + views.views.follow_offset)
    # the operator orbits: the page's own offset from the tool is kept as the tool moves
    a.camera.position = a.camera.position + np.array([0.05, -0.02, 0.0])
    a.camera.look_at = tool.copy()
    offset = a.camera.position - a.camera.look_at
    session.arm.jog_tool(frame="world", constraint="x", motion="translate", displacement=np.array([0.03, 0.0, 0.0]))
    moved = np.asarray(session.arm.view().world_T_tcp)[:3, 3]
    assert np.linalg.norm(moved - tool) > 0.01
    views.follow(session.arm.view().world_T_tcp)  # what the console does on each ArmChanged
    np.testing.assert_allclose(a.camera.look_at, moved, atol=1e-12)
    np.testing.assert_allclose(a.camera.position - a.camera.look_at, offset, atol=1e-12)
    np.testing.assert_allclose(b.camera.position, front.position)
    # another preset ends following
    views.press(a, "top")
    assert not views.following(11)
    before = a.camera.position.copy()
    views.follow(np.eye(4))
    np.testing.assert_allclose(a.camera.position, before)


def test_the_terrain_is_shaded_by_height_and_the_arm_is_opaque() -> None:
    from webui.scene_util import HEIGHT_STOPS, height_shaded

    from shared.robots.shapes import link_meshes
    from shared.terrain.cell import TERRAIN_OBJECT

    for name in ("rover_terrain", "rover_flat", "rover_stone"):
        cell = load_cell(ASSETS_DIR / "cells" / f"{name}.toml")
        terrain = cell.object(TERRAIN_OBJECT)
        mesh = height_shaded(link_meshes(terrain.shapes), terrain.world_T_object)
        colours = np.asarray(mesh.visual.vertex_colors)
        assert colours.shape == (len(mesh.vertices), 4) and np.all(colours[:, 3] == 255)
        # darker than the white grid everywhere: no colour near white
        assert colours[:, :3].max() < 200
        if name == "rover_terrain":  # relief: low ground darker than high ground
            z = np.asarray(mesh.vertices)[:, 2] + terrain.world_T_object[2, 3]
            lum = colours[:, :3].astype(float) @ [0.2126, 0.7152, 0.0722]
            assert np.corrcoef(z, lum)[0, 1] > 0.8
            assert len(np.unique(colours[:, :3], axis=0)) > 50
    assert HEIGHT_STOPS.shape[1] == 3
    # the virtual arm: every link drawn from fully opaque colours
    from webui.scene_util import colored

    cell = load_cell(ASSETS_DIR / "cells" / "rover_terrain.toml")
    for shapes in cell.robot.shapes.values():
        if shapes:
            mesh = colored(link_meshes(shapes), shapes[0].color)
            assert np.all(np.asarray(mesh.visual.face_colors)[:, 3] == 255)


def test_presets_class_keeps_no_page_after_it_leaves(peg_console) -> None:
    _, _, console = peg_console
    views: CameraPresets = console.views
    a = FakeClient(21, FakeCamera((1.0, 0.0, 1.0), (0.0, 0.0, 0.0)))
    views.press(a, "follow")
    assert views.following(21)
    views._forget(a)  # what viser's disconnect callback runs
    assert not views.following(21)
