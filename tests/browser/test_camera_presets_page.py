"""The view's presets on the real page (issue 37, "a view of the work"): two pages open on one
console; pressing a preset on one moves that page's camera, and the other page's camera stays
where it was; "Follow tool" then moves the first page's camera with the virtual arm's tool.

The console runs in this process (viser on a loopback port, the session and ``build_console``)
so the test reads each page's camera as the page itself reports it: viser's per-client camera
handle, updated by the camera messages the page sends whenever its camera moves.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest
import viser

from console_page import ConsolePage
from server.console import Session
from shared.cells.loader import DEFAULT_CELL, load_cell
from support import free_port, screenshot_if_failed, wait_for
from webui.console import build_console

pytestmark = [pytest.mark.browser, pytest.mark.random_order(disabled=True)]

TOL = 2e-3  # m: the page reports its camera in float32


class Reports:
    """Every camera pose each page reported (client id -> list of (position, look_at)), and the
    field of view it last reported."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.poses: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
        self.fov: dict[int, float] = {}

    def watch(self, client: viser.ClientHandle) -> None:
        def reported(camera: viser.CameraHandle) -> None:
            with self.lock:
                self.poses.setdefault(client.client_id, []).append(
                    (np.array(camera.position, dtype=float), np.array(camera.look_at, dtype=float)))
                self.fov[client.client_id] = float(camera.fov)

        client.camera.on_update(reported)

    def latest(self, client_id: int) -> tuple[np.ndarray, np.ndarray] | None:
        with self.lock:
            poses = self.poses.get(client_id)
            return poses[-1] if poses else None

    def count(self, client_id: int) -> int:
        with self.lock:
            return len(self.poses.get(client_id, ()))

    def since(self, client_id: int, count: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """The poses the page reported after its first ``count``."""
        with self.lock:
            return list(self.poses.get(client_id, ())[count:])


@pytest.fixture(scope="module")
def console_here():
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    session = Session(load_cell(DEFAULT_CELL))
    reports = Reports()
    server.on_client_connect(reports.watch)
    console = build_console(server, session)
    yield server, session, console, reports
    session.close()
    server.stop()


@pytest.fixture(scope="module")
def pages(console_here, chromium):
    server, *_ = console_here
    url = f"http://127.0.0.1:{server.get_port()}/"
    opened = []
    for _ in range(2):
        context = chromium.new_context(viewport={"width": 1400, "height": 900})
        page = context.new_page()
        before = set(server.get_clients())
        page.goto(url)
        page.wait_for_selector("canvas", timeout=60_000)
        page.get_by_role("button", name="Front", exact=True).wait_for(timeout=60_000)
        new = wait_for(lambda: set(server.get_clients()) - before, timeout=60, what="the page connected")
        opened.append((context, page, server.get_clients()[new.pop()]))
    yield opened
    for context, *_ in opened:
        context.close()


@pytest.fixture
def two(pages, request):
    yield pages
    for _, page, _ in pages:
        screenshot_if_failed(request, page)


def reported_at(reports: Reports, client_id: int, position: np.ndarray, look_at: np.ndarray, what: str,
                timeout: float = 30.0) -> None:
    def there() -> bool:
        pose = reports.latest(client_id)
        return pose is not None and np.allclose(pose[0], position, atol=TOL) and np.allclose(pose[1], look_at, atol=TOL)

    wait_for(there, timeout, what=f"{what} (last report {reports.latest(client_id)})")


def unchanged(reports: Reports, client: viser.ClientHandle, before, count: int) -> None:
    """The page's camera stands at ``before``: its handle, and every report since ``count`` (a
    page may report its camera again, late, from where it already was: no move)."""
    for pose in reports.since(client.client_id, count):
        np.testing.assert_allclose(pose[0], before[0], atol=TOL)
        np.testing.assert_allclose(pose[1], before[1], atol=TOL)
    np.testing.assert_allclose(client.camera.position, before[0], atol=TOL)
    np.testing.assert_allclose(client.camera.look_at, before[1], atol=TOL)


def test_both_pages_open_at_the_cells_default_view(console_here, two) -> None:
    _, _, console, reports = console_here
    front = console.views.views.front
    for _, _, client in two:
        reported_at(reports, client.client_id, front.position, front.look_at, f"page {client.client_id} at the front view")


def test_a_preset_moves_this_pages_camera_and_not_the_others(console_here, two) -> None:
    _, _, console, reports = console_here
    views = console.views.views
    (_, page_a, client_a), (_, _, client_b) = two
    b_before = reports.latest(client_b.client_id)
    b_count = reports.count(client_b.client_id)
    ui = ConsolePage(page_a, None)
    ui.tab("Drive")
    for label, preset in (("Top", "top"), ("Side", "side"), ("Front", "front")):
        ui.click(label)
        target = views.preset(preset)
        reported_at(reports, client_a.client_id, target.position, target.look_at, f"page A at the {preset} view")
        # the top view looks from far with a narrow field; the others with the page's usual one
        wait_for(lambda: abs(reports.fov[client_a.client_id] - target.fov) < 1e-3, what=f"the {preset} view's field")
    # the other page was told nothing: a preset sets a page's camera handle at once, in the click's
    # callback, before the message leaves; A's page has reported the new pose, so any change to B's
    # handle would show by now. B's page reported no new camera either, and it stands where it stood.
    unchanged(reports, client_b, b_before, b_count)


def test_follow_tool_moves_only_the_following_pages_camera(console_here, two) -> None:
    _, session, console, reports = console_here
    (_, page_a, client_a), (_, _, client_b) = two
    b_before = reports.latest(client_b.client_id)
    b_count = reports.count(client_b.client_id)
    ui = ConsolePage(page_a, None)
    ui.click("Follow tool")
    tool = np.asarray(session.arm.view().world_T_tcp)[:3, 3]
    offset = console.views.views.follow_offset
    reported_at(reports, client_a.client_id, tool + offset, tool, "page A looking at the tool")
    session.arm.jog_tool(frame="world", constraint="y", motion="translate", displacement=np.array([0.0, 0.06, 0.0]))
    moved = np.asarray(session.arm.view().world_T_tcp)[:3, 3]
    assert moved[1] - tool[1] > 0.05
    reported_at(reports, client_a.client_id, moved + offset, moved, "page A moved with the tool")
    unchanged(reports, client_b, b_before, b_count)
    # a preset ends following: the next move of the tool leaves page A where it is (the arm's
    # events reach the cameras within the jog's call: nothing is left to wait for)
    ui.click("Front")
    front = console.views.views.front
    reported_at(reports, client_a.client_id, front.position, front.look_at, "page A back at the front view")
    a_before, a_count = reports.latest(client_a.client_id), reports.count(client_a.client_id)
    session.arm.jog_tool(frame="world", constraint="y", motion="translate", displacement=np.array([0.0, -0.06, 0.0]))
    assert np.linalg.norm(np.asarray(session.arm.view().world_T_tcp)[:3, 3] - moved) > 0.05
    unchanged(reports, client_a, a_before, a_count)
    # after all of page A's presets and follows, page B still reports the view it opened with
    position, look_at = reports.latest(client_b.client_id)
    np.testing.assert_allclose(position, front.position, atol=TOL)
    np.testing.assert_allclose(look_at, front.look_at, atol=TOL)
