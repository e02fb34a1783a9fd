"""The Drive tab in headless Chromium with the mouse (issue 16, findings 5 and 7, and the second
"Done when"): generation is on from the start with its toggle on the Drive tab, a straight drag
of the gizmo writes one statement in the chosen frame, the ring of "rotate in the xy plane"
turns the tool, and a chosen joint gets a ring that turns it.

Where a handle is on the canvas is worked out here from the camera the console starts with
(looking at the tool from ``CAMERA_OFFSET``, viser's 75 deg vertical field of view) and the
handle sizes of the gizmo (drei's PivotControls: arrows as long as the gizmo's scale, rings a
quarter arc of radius 0.65 scale between the two other axes). One console (no robot) serves the
module; its tests are steps on it in their written order (the first drags where the camera
still looks at the start pose).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from console_page import ConsolePage, wait_for
from support import screenshot_if_failed, start_console, stop_process
from webui.console import CAMERA_OFFSET
from webui.drive_gizmo import GIZMO_SCALE

pytestmark = [pytest.mark.browser, pytest.mark.random_order(disabled=True)]

FOV = math.radians(75.0)


@pytest.fixture(scope="module")
def module_ui(tmp_path_factory, chromium):
    console = start_console(tmp_path_factory.mktemp("drive"), "--no-robot", timeout=180.0)  # a loaded machine starts it slowly
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    ui = ConsolePage(context.new_page(), console)
    ui.open()
    ui.start_tool = np.asarray(ui.session()["arm"]["world_T_tcp"])[:3, 3]  # where the camera looks
    yield ui
    context.close()
    stop_process(console.proc)


@pytest.fixture
def ui(module_ui: ConsolePage, request) -> ConsolePage:
    yield module_ui
    screenshot_if_failed(request, module_ui.page)


def to_canvas(ui: ConsolePage, world_p: np.ndarray) -> tuple[float, float]:
    """Canvas pixel of a world point, for the camera the console starts with."""
    box = ui.page.locator("canvas").first.bounding_box()
    look = ui.start_tool
    eye = look + np.array(CAMERA_OFFSET)
    f = (look - eye) / np.linalg.norm(look - eye)
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = np.asarray(world_p, float) - eye
    focal = (box["height"] / 2) / math.tan(FOV / 2)
    x, y, z = d @ r, d @ u, d @ f
    return box["x"] + box["width"] / 2 + focal * x / z, box["y"] + box["height"] / 2 - focal * y / z


def program(ui: ConsolePage) -> list[dict]:
    return [e for e in ui.session()["program"]["entries"] if e["kind"] != "EMPTY"]


def tool_mm(ui: ConsolePage) -> np.ndarray:
    return np.asarray(ui.session()["arm"]["tool_xyz_mm"])


def drag_until_moved(ui: ConsolePage, grabs: list[np.ndarray], pull: tuple[float, float], moved) -> None:
    """Press at the grab points (world) in turn and pull by ``pull`` pixels, each drag once and
    its effect awaited (``ConsolePage.drag_until``), until ``moved()``."""
    ui.drag_until([to_canvas(ui, grab) for grab in grabs], pull, moved, steps=14)


def drive_toggle(ui: ConsolePage):
    return ui.row("Generate statements").locator("input[type=checkbox]").first


def test_generation_is_on_from_the_start_and_the_drive_tab_toggles_the_one_flag(ui: ConsolePage) -> None:
    assert ui.session()["program"]["auto_generate"]
    ui.tab("Drive")
    toggle = drive_toggle(ui)
    assert toggle.is_checked()
    toggle.click()
    wait_for(lambda: not ui.session()["program"]["auto_generate"], what="generation off from the Drive tab")
    ui.tab("Program")
    wait_for(lambda: not ui.page.get_by_label("Automatic generation", exact=True).is_checked(), what="the Program tab shows it off")
    ui.page.get_by_label("Automatic generation", exact=True).click()
    wait_for(lambda: ui.session()["program"]["auto_generate"], what="generation on from the Program tab")
    ui.tab("Drive")
    wait_for(lambda: drive_toggle(ui).is_checked(), what="the Drive tab shows it on")


def test_a_straight_drag_on_the_z_arrow_writes_one_statement_in_the_chosen_frame(ui: ConsolePage) -> None:
    """Done when: the approach driven by the gizmo, generation on, at most one statement per
    straight stroke, in the chosen frame (Frame = work: the statement ends IN WORK)."""
    ui.tab("Drive")
    ui.choose("Frame", "work")
    ui.choose("Direction", "z axis")
    start = tool_mm(ui)
    tool = ui.start_tool
    work_z = np.array([0.0, 0.0, 1.0])  # the table top is level: work z is world z
    grabs = [tool + work_z * GIZMO_SCALE * f for f in (0.55, 0.7, 0.4, 0.85)]
    drag_until_moved(ui, grabs, (0.0, -60.0), lambda: abs(tool_mm(ui)[2] - start[2]) > 2.0)
    after = tool_mm(ui)
    assert after[2] > start[2] + 2.0  # pulled up
    np.testing.assert_allclose(after[:2], start[:2], atol=0.5)  # the z axis alone
    entries = wait_for(lambda: (p := program(ui)) and p, what="a generated statement")
    time.sleep(0.6)  # any late segment of the same stroke
    entries = program(ui)
    assert len(entries) == 1, [e["text"] for e in entries]
    assert entries[0]["kind"] == "DRAW" and entries[0]["text"].endswith("IN WORK"), entries[0]["text"]
    ui.tab("Program")
    ui.text_appears(r"1: DRAW TO \([^)]*\) mm IN WORK")


def test_the_ring_of_rotate_in_the_xy_plane_turns_the_tool(ui: ConsolePage) -> None:
    ui.tab("Drive")
    ui.choose("Frame", "world")
    ui.choose("Direction", "xy plane")
    ui.choose("Motion", "rotate")
    before = np.asarray(ui.session()["arm"]["tool_rpy_deg"])
    now_mm = tool_mm(ui) / 1e3
    radius = 0.65 * GIZMO_SCALE

    def turned() -> bool:
        d = np.asarray(ui.session()["arm"]["tool_rpy_deg"]) - before
        return bool(np.max(np.abs((d + 180.0) % 360.0 - 180.0)) > 1.0)

    # the quarter arc from +x to +y about the tool: grab it near its +x end, pull along it
    grabs = [now_mm + radius * np.array([math.cos(a), math.sin(a), 0.0]) for a in np.radians([25.0, 40.0, 15.0, 55.0])]
    drag_until_moved(ui, grabs, (-25.0, -8.0), turned)
    np.testing.assert_allclose(tool_mm(ui) / 1e3, now_mm, atol=0.001)  # turned in place
    kinds = [e["kind"] for e in program(ui)]
    assert kinds[-1] == "ROTATE"


def test_choosing_a_joint_offers_a_ring_that_turns_that_joint(ui: ConsolePage) -> None:
    from shared.cells.loader import DEFAULT_CELL, load_cell  # noqa: PLC0415 - where J3's axis is, to find its ring
    from shared.robots.handles import joint_handle  # noqa: PLC0415

    ui.tab("Drive")
    ui.choose("Moving part", "J3")
    cell = load_cell(DEFAULT_CELL)
    q0 = np.asarray(ui.session()["arm"]["q"])
    handle = joint_handle(cell.robot, q0, 3, cell.world_T_base)
    radius = 0.65 * GIZMO_SCALE
    grabs = [handle[:3, 3] + radius * (math.cos(a) * handle[:3, 0] + math.sin(a) * handle[:3, 1]) for a in np.radians([45.0, 30.0, 60.0, 15.0, 75.0])]

    def turned() -> bool:
        return abs(ui.session()["arm"]["q"][2] - q0[2]) > math.radians(0.5)

    drag_until_moved(ui, grabs, (25.0, 25.0), turned)
    q = np.asarray(ui.session()["arm"]["q"])
    np.testing.assert_allclose(np.delete(q, 2), np.delete(q0, 2), atol=1e-9)  # J3 alone
    assert program(ui)[-1]["text"].startswith("DRIVE J3 TO")


def test_a_slider_dragged_with_pauses_writes_one_drive(ui: ConsolePage) -> None:
    ui.tab("Drive")
    before = len(program(ui))
    q6 = ui.session()["arm"]["q_deg"][5]
    thumb = ui.row("J6").locator(".mantine-Slider-thumb").first
    thumb.scroll_into_view_if_needed()  # the joints sit below the fold of the Drive tab
    ui.settle()  # drawn where it scrolled to
    box = thumb.bounding_box()
    assert box is not None
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    ui.page.mouse.move(x, y)
    ui.page.mouse.down()
    for k in range(1, 4):  # a hand that drags, stops a moment (longer than a release), drags on
        ui.page.mouse.move(x + 12 * k, y, steps=6)
        time.sleep(0.7)
    ui.page.mouse.up()
    wait_for(lambda: abs(ui.session()["arm"]["q_deg"][5] - q6) > 1.0, what="J6 turned by the slider")
    time.sleep(0.8)  # the slider's release (a pause) closes the last segment
    added = program(ui)[before:]
    assert [e["text"].split()[:2] for e in added] == [["DRIVE", "J6"]], [e["text"] for e in added]
    assert float(added[0]["text"].split()[3]) == pytest.approx(ui.session()["arm"]["q_deg"][5], abs=0.01)
