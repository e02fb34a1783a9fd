"""The operator's console in headless Chromium, driven with mouse and keyboard only: drive and
generate, edit the program, preview, submit over a 200 ms link, STOP, collide with the table.

The tests share one console (``teleprog up --delay-ms 200``: console, link and telerobot as
separate processes); each opens a fresh page, starts from an empty program by loading an empty
program file, and checks what the page shows against the session's state read from the API
(reads only).
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from console_page import ConsolePage, wait_for
from support import screenshot_if_failed

# one page on one console for the module, its tests are steps an operator takes in turn: kept in their written order under --random-order
pytestmark = [pytest.mark.browser, pytest.mark.random_order(disabled=True)]

DOCS_SCREENSHOT = Path(__file__).resolve().parents[2] / "docs" / "console.png"

# statements small enough to stay in the free air above the table (work frame, mm)
UP = "DRAW TO (0, -80, 200) mm IN WORK"
ACROSS = "DRAW TO (60, -80, 200) mm IN WORK"


@pytest.fixture(scope="module")
def module_ui(linked_console, chromium):
    """One page on the shared console for the whole module (its first frame takes seconds)."""
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    ui = ConsolePage(context.new_page(), linked_console)
    ui.open()
    yield ui
    context.close()


@pytest.fixture
def ui(module_ui: ConsolePage, request) -> ConsolePage:
    module_ui.reset_program()
    yield module_ui
    screenshot_if_failed(request, module_ui.page)


def entries(ui: ConsolePage) -> list[dict]:
    return ui.session()["program"]["entries"]


def test_drag_gizmo_moves_the_tool_and_statements_appear(ui: ConsolePage) -> None:
    # first in the module: the camera still looks at the tool where the console started
    ui.tab("Program")
    assert ui.page.get_by_label("Automatic generation", exact=True).is_checked()  # on from the start (issue 16)
    wait_for(lambda: ui.session()["program"]["auto_generate"], what="automatic generation on")
    before = ui.session()["arm"]["tool_xyz_mm"]
    after = ui.drag_gizmo_x(60)
    assert after[0] > before[0] + 5.0  # pulled right: +x in the world
    assert abs(after[2] - before[2]) < 1.0  # the xy-plane constraint kept the height
    program = wait_for(lambda: (e := entries(ui)) and len(e) > 1 and e, what="a generated statement")
    first = program[0]
    assert first["kind"] in ("DRAW", "MOVES", "MOVE")
    # the page lists it, numbered, ahead of the selected trailing empty statement
    ui.text_appears(r"1: " + first["kind"])
    ui.text_appears(r"▶ " + rf"{len(program)}: \(empty statement\)")
    ui.page.get_by_label("Automatic generation", exact=True).click()
    wait_for(lambda: not ui.session()["program"]["auto_generate"], what="automatic generation off")


def test_select_edit_delete_undo(ui: ConsolePage) -> None:
    ui.insert_statement(UP)
    ui.insert_statement(ACROSS)
    wait_for(lambda: len(entries(ui)) == 3, what="two statements")
    ui.text_appears(r"2: DRAW TO \(60")
    # select the first statement with the selector
    ui.choose("Selected", "1: DRAW TO (0", exact=False)
    wait_for(lambda: ui.session()["program"]["selected"] == 0, what="statement 1 selected")
    ui.text_appears(r"▶ 1: DRAW TO \(0")
    # its WITH condition may change although it is not the last action
    ui.type_into("Selected text", UP + " WITH SPEED 20 mm/s")
    ui.click("Replace")
    wait_for(lambda: "WITH SPEED 20" in entries(ui)[0]["text"], what="statement 1 has WITH SPEED")
    ui.text_appears(r"1: DRAW TO \(0[^\n]*WITH SPEED 20")
    # free editing (the default): it goes although an action follows it, and Undo brings it back
    ui.click("Delete")
    wait_for(lambda: len(entries(ui)) == 2, what="statement 1 deleted")
    assert ui.session()["program"]["refusal"] is None
    ui.click("Undo")
    wait_for(lambda: len(entries(ui)) == 3, what="statement 1 back")
    assert "WITH SPEED 20" in entries(ui)[0]["text"]
    # select the last one and delete it, then undo the deletion
    ui.choose("Selected", "2: DRAW TO (60", exact=False)
    wait_for(lambda: ui.session()["program"]["selected"] == 1, what="statement 2 selected")
    ui.click("Delete")
    wait_for(lambda: len(entries(ui)) == 2, what="statement 2 deleted")
    ui.click("Undo")
    wait_for(lambda: len(entries(ui)) == 3, what="deletion undone")
    ui.text_appears(r"2: DRAW TO \(60")


def test_preview_a_range(ui: ConsolePage) -> None:
    ui.insert_statement(UP)
    ui.insert_statement(ACROSS)
    wait_for(lambda: len(entries(ui)) == 3, what="two statements")
    ui.tab("Preview")
    ui.set_number("From statement", 1)
    ui.set_number("To statement", 2)
    ui.click("Start preview")
    wait_for(lambda: ui.session()["preview"]["active"], what="preview running")
    ui.text_appears(r"Statements 1-2: t = 0\.00")
    q_start = ui.session()["preview"]["q"]
    ui.click("Step")
    ui.text_appears(r"Playing statement [12]")
    stepped = wait_for(lambda: (p := ui.session()["preview"])["t"] > 0 and p, what="preview stepped")
    assert stepped["q"] != q_start  # the arm stands at the end of statement 1
    ui.click("Play")
    done = wait_for(lambda: (p := ui.session()["preview"])["t"] >= p["duration"] - 1e-6 and not p["playing"] and p,
                    timeout=30, what="preview played to its end")
    ui.text_appears(rf"t = {done['duration']:.2f} / {done['duration']:.2f} s \(paused\)")
    ui.text_appears(r"No warnings\.")
    # while previewing only selection is allowed; the program is unchanged
    ui.tab("Program")
    ui.click("Delete")
    ui.text_appears(r"cannot delete|preview")
    assert len(entries(ui)) == 3
    ui.tab("Preview")
    ui.click("End")
    wait_for(lambda: not ui.session()["preview"]["active"], what="preview ended")


def _free_regime(ui: ConsolePage) -> None:
    ui.choose("Regime", "free")
    wait_for(lambda: ui.session()["regime"]["regime"] == "free", what="free regime")


def test_submit_over_the_link_and_statuses_reach_done(ui: ConsolePage, tmp_path: Path) -> None:
    ui.insert_statement(UP)
    ui.insert_statement(ACROSS + " WITH SPEED 20 mm/s")  # 3 s: still running for the picture
    wait_for(lambda: len(entries(ui)) == 3, what="two statements")
    _free_regime(ui)
    ui.tab("Submit")
    ui.set_number("Submit from", 1)
    ui.set_number("Submit to", 2)
    ui.click("Submit range")
    # the statements leave the program at once and show in the sent list
    wait_for(lambda: len(entries(ui)) == 1, what="program emptied by the submission")
    ui.text_appears(r"2 sent")
    ui.text_appears(r"#\d+ DRAW TO \(0")
    ui.text_appears(r"DRAW TO \(60[^\n]*: running", timeout=20)
    ui.dismiss_notices(wait=1.0)
    time.sleep(0.5)  # let the ghost and the predicted path catch up with the run
    shot = tmp_path / "console.png"
    ui.page.screenshot(path=str(shot))  # the main view mid-run: ghost, path, sent list
    if os.environ.get("TELEPROG_UPDATE_SCREENSHOT"):
        DOCS_SCREENSHOT.parent.mkdir(exist_ok=True)
        shutil.copy(shot, DOCS_SCREENSHOT)
    # the operator goes on programming while the robot works
    ui.insert_statement("DRAW TO (60, 0, 200) mm IN WORK WITH SPEED 30 mm/s")
    ui.insert_statement("ROTATE TO (180, 0, 90) deg IN WORK")
    ui.text_appears(r"2: ROTATE")
    sent = wait_for(lambda: (s := ui.session()["sent"])["pending"] == 0 and s, timeout=60, what="all statements final")
    assert [i["status"] for i in sent["items"]][-2:] == ["done", "done"]
    assert len(entries(ui)) == 3  # statements added meanwhile stay in the program
    numbers = [i["number"] for i in sent["items"][-2:]]
    assert numbers[1] == numbers[0] + 1
    ui.tab("Submit")
    ui.text_appears(rf"#{numbers[1]} DRAW TO \(60[^\n]*: done, ran \d+\.\d s")
    ui.text_appears(r"robot idle")


def test_stop_during_a_long_move(ui: ConsolePage) -> None:
    ui.insert_statement("DRAW TO (0, -80, 300) mm IN WORK WITH SPEED 5 mm/s")  # about 25 s of motion
    wait_for(lambda: len(entries(ui)) == 2, what="a slow statement")
    _free_regime(ui)
    ui.tab("Submit")
    ui.click("Submit range")
    # the robot's report through the API: the page's "running" line is the submit test's
    # business (a fresh-clone run once never showed it here while the API said running; see the
    # closing note of 2026-12-04)
    wait_for(lambda: any(i["status"] == "running" for i in ui.session()["sent"]["items"]), timeout=30,
             what="the slow statement running on the robot")
    time.sleep(1.0)  # let it move
    q_running = ui.session()["remote"]["q"]
    ui.click("STOP")
    ui.text_appears(r"robot stopped", timeout=10)
    q_stopped = ui.session()["remote"]["q"]
    assert q_stopped != q_running  # it had moved before the STOP arrived
    time.sleep(1.0)
    # and stays still after it (a braked physical arm settles by some 1e-5 rad, no more)
    assert ui.session()["remote"]["q"] == pytest.approx(q_stopped, abs=2e-4)
    assert ui.session()["sent"]["items"][-1]["status"] not in ("done",)
    ui.page.get_by_role("button", name="Abort", exact=True).click()
    wait_for(lambda: ui.session()["sent"]["pending"] == 0, timeout=20, what="aborted statement final")


def test_drive_into_the_table_shows_the_collision(ui: ConsolePage) -> None:
    ui.tab("Drive")
    ui.set_number("J1", 10)  # swing the tool over the bare table, clear of the plate
    wait_for(lambda: abs(ui.session()["arm"]["q_deg"][0] - 10) < 0.2, what="J1 at 10 deg")
    # lower the arm with the shoulder, a few degrees at a time, until it meets the table
    collision = None
    for j2 in np.arange(ui.session()["arm"]["q_deg"][1], 40.0, 3.0):
        ui.set_number("J2", round(float(j2), 1))
        wait_for(lambda: abs(ui.session()["arm"]["q_deg"][1] - round(float(j2), 1)) < 0.2, what=f"J2 at {j2:.1f}")
        collision = ui.session()["collision"]
        if collision["colliding"]:
            break
    assert collision is not None and collision["colliding"], "lowering the shoulder never reached the table"
    assert any("table" in pair for pair in collision["pairs"])
    assert sum(len(t) for t in collision["triangles"].values()) > 0  # red triangles to draw
    ui.text_appears(r"COLLISION:[^\n]*table")
