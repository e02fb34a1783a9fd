"""Correcting the virtual peg from the front camera's image, from the page (thesis §4.2.3):
the operator types the pixels of the peg's four feature points and the virtual peg moves to where
the camera saw it; points in the wrong order are refused with the reason."""

from __future__ import annotations

import numpy as np
import pytest

from console_page import ConsolePage, wait_for
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.spatial import pose_to_transform
from support import ARTIFACTS, start_console, stop_process

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def ui(tmp_path_factory, chromium, request):
    running = start_console(tmp_path_factory.mktemp("locate"), "--no-robot")
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    page = ConsolePage(context.new_page(), running, quick_clicks=True)
    page.open()
    yield page
    ARTIFACTS.mkdir(exist_ok=True)
    page.page.screenshot(path=str(ARTIFACTS / "locate_page.png"))
    context.close()
    stop_process(running.proc)


def test_typed_image_points_move_the_virtual_peg(ui: ConsolePage) -> None:
    cell = load_cell(DEFAULT_CELL)
    peg = cell.object("peg")
    real = peg.world_T_object @ pose_to_transform(np.array([0.003, -0.002, 0.0]), np.radians([0.0, 0.0, 3.0]))
    pixels = cell.cameras["front"].project(peg.keypoints @ real[:3, :3].T + real[:3, 3])
    ui.tab("Drive")
    ui.page.get_by_text("Correct an object from a camera image").click()
    # wrong order first: refused, nothing moves
    ui.type_into("Image points (u v; ...)", "; ".join(f"{u:.3f} {v:.3f}" for u, v in pixels[[2, 0, 3, 1]]))
    ui.click("Correct pose from image")
    ui.text_appears(r"locate peg refused: .*(do not fit|behind)")
    assert "peg" not in ui.session()["arm"]["object_poses"] or np.allclose(
        ui.session()["arm"]["object_poses"]["peg"], peg.world_T_object)
    ui.type_into("Image points (u v; ...)", "; ".join(f"{u:.3f} {v:.3f}" for u, v in pixels))
    ui.click("Correct pose from image")
    ui.text_appears(r"peg located from camera front: moved 3\.6 mm")
    moved = wait_for(lambda: ui.session()["arm"]["object_poses"].get("peg"), what="the virtual peg moved")
    np.testing.assert_allclose(moved, real, atol=2e-5)  # pixels typed to 0.001 px
