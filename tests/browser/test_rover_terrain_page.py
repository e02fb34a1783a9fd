"""The rover terrain cell in headless Chromium, mouse and keyboard only: the clearance readout,
the virtual sensors on demand, a target picked by clicking the terrain, a placement typed as a
ground position and its program inserted, and the arm driven onto the ground shown in red.

The console runs alone (``--no-robot``): nothing here needs the telerobot. The session's state
is read through the API to check what the page did; every action goes through the page.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest

from console_page import ConsolePage, wait_for
from shared.cells.loader import load_cell
from shared.terrain.cell import cell_terrain_mesh
from support import ARTIFACTS, screenshot_if_failed, start_console, stop_process

# one page on one rover console for the module, its tests are steps in turn: kept in their written order under --random-order
pytestmark = [pytest.mark.browser, pytest.mark.random_order(disabled=True)]

ROVER_TERRAIN = Path(__file__).resolve().parents[2] / "assets" / "cells" / "rover_terrain.toml"


@pytest.fixture(scope="module")
def rover_ui(tmp_path_factory, chromium):
    running = start_console(tmp_path_factory.mktemp("rover"), "--cell", str(ROVER_TERRAIN), "--no-robot")
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    ui = ConsolePage(context.new_page(), running)
    ui.open()
    yield ui
    context.close()
    stop_process(running.proc)


@pytest.fixture
def ui(rover_ui: ConsolePage, request) -> ConsolePage:
    yield rover_ui
    screenshot_if_failed(request, rover_ui.page)


def terrain(ui: ConsolePage) -> dict:
    return ui.console.api("GET", "/api/terrain").json()


def mesh_height(x: float, y: float) -> float:
    """Height (world, m) of the top terrain triangle over ground position (x, y), by barycentric
    interpolation over the cell's mesh: an oracle independent of the console's ray picking."""
    mesh = cell_terrain_mesh(load_cell(ROVER_TERRAIN))
    a, b, c = (mesh.vertices[mesh.faces[:, i]] for i in range(3))
    d = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
    ok = np.abs(d) > 1e-15  # triangles seen edge-on from above cover no ground
    w0 = ((b[:, 1] - c[:, 1]) * (x - c[:, 0]) + (c[:, 0] - b[:, 0]) * (y - c[:, 1])) / np.where(ok, d, 1.0)
    w1 = ((c[:, 1] - a[:, 1]) * (x - c[:, 0]) + (a[:, 0] - c[:, 0]) * (y - c[:, 1])) / np.where(ok, d, 1.0)
    w2 = 1.0 - w0 - w1
    inside = ok & (w0 >= -1e-12) & (w1 >= -1e-12) & (w2 >= -1e-12)
    assert inside.any(), f"({x}, {y}) is not over the terrain"
    z = w0 * a[:, 2] + w1 * b[:, 2] + w2 * c[:, 2]
    return float(np.max(z[inside]))


def test_clearance_and_sensors_on_demand(ui: ConsolePage) -> None:
    ui.tab("Terrain")
    shown = ui.text_appears(r"Exact clearance: [\d.]+ mm")
    assert float(re.search(r"([\d.]+) mm", shown).group(1)) == pytest.approx(terrain(ui)["distance"] * 1e3, abs=0.06)
    assert terrain(ui)["sensors"] is None
    ui.page.get_by_label("Show virtual sensors", exact=True).click()
    wait_for(lambda: terrain(ui)["sensors"] is not None, what="sensors shown")
    ui.page.get_by_label("Show virtual sensors", exact=True).click()
    wait_for(lambda: terrain(ui)["sensors"] is None, what="sensors hidden")


def test_click_on_the_terrain_picks_the_target(ui: ConsolePage) -> None:
    ui.tab("Terrain")
    ui.page.get_by_label("Pick target on click", exact=True).click()
    cx, cy = ui.canvas_center()
    # the camera looks at the tool from the front and above: below the centre lies the ground
    for dy in (120, 180, 240):
        ui.page.mouse.click(cx, cy + dy)
        try:
            placed = wait_for(lambda: ui.console.api("GET", "/api/terrain/placement").json(), timeout=5, what="a target")
            break
        except AssertionError:
            continue
    else:
        raise AssertionError("no click below the tool picked a terrain point")
    ui.page.get_by_label("Pick target on click", exact=True).click()  # camera moves no longer pick
    x, y, z = (v * 1e3 for v in placed["world_p_target"])
    ui.text_appears(rf"Target \({x:.1f}, {y:.1f}, {z:.1f}\) mm")
    # the picked point lies on the ground: checked here against the cell's terrain mesh itself
    # (no request that changes the session): its z is the height of the mesh at its (x, y)
    np.testing.assert_allclose(placed["world_p_target"][2], mesh_height(*placed["world_p_target"][:2]), atol=1e-6)


def test_typed_ground_position_placement_enters_the_program(ui: ConsolePage) -> None:
    ui.tab("Terrain")
    ui.set_number("Target x (mm)", 700)
    ui.set_number("Target y (mm)", 0)
    ui.click("Plan at ground position")
    placed = wait_for(lambda: (p := ui.console.api("GET", "/api/terrain/placement").json())
                      and abs(p["world_p_target"][0] - 0.7) < 1e-9 and p, what="placement at (700, 0)")
    assert placed["candidates"], placed["message"]
    ui.text_appears(r"Target \(700\.0, -?0\.0, [\d.-]+\) mm: \d+ safe configuration")
    before = len(ui.session()["program"]["entries"])
    ui.click("Insert placement program")
    # the whole placement program, not its first line: the page's insert may land line by line
    wait_for(lambda: [e["text"] for e in ui.session()["program"]["entries"] if e["kind"] != "EMPTY"][-len(placed["program"]):]
             == placed["program"], what=f"the placement program inserted after the {before} entries there were")
    ui.click("Show best configuration")
    wait_for(lambda: np.allclose(ui.session()["arm"]["q"], placed["candidates"][0]["q"], atol=1e-9), what="arm at the best")
    ui.text_appears(r"Instrument head to ground: [\d.]+ mm")
    head = terrain(ui)["head_distance"]
    assert 0.0 < head <= 0.030


def test_arm_on_the_ground_shows_red_triangles_and_the_warning(ui: ConsolePage) -> None:
    ui.tab("Drive")
    for joint, value in (("J1", -40.0), ("J2", -40.0), ("J3", -200.0)):
        ui.set_number(joint, value)
        wait_for(lambda: abs(ui.session()["arm"]["q_deg"][int(joint[1]) - 1] - value) < 0.2, what=f"{joint} at {value}")
        time.sleep(0.2)
    view = wait_for(lambda: (t := terrain(ui))["in_collision"] and t, what="the arm on the ground")
    assert view["contact_corners"]
    ui.text_appears(r"COLLISION:[^\n]*link3 / terrain")
    ui.tab("Terrain")
    ui.text_appears(r"ARM TOUCHES THE GROUND \(link3[^)]*\); \d+ triangle\(s\) in red")
    ARTIFACTS.mkdir(exist_ok=True)
    ui.page.screenshot(path=str(ARTIFACTS / "rover_terrain_contact.png"))
