"""Regimes that explain themselves (issue 16, finding 6), in headless Chromium with mouse and
keyboard only: the header's coloured banner names the regime, what it does and who chose it; a
drag in the free zone says on the Drive tab that it runs on the robot; the Submit tab says what
Submit needs before the click; "Preview and submit" at a chosen preview speed sends a range
without a real-time wait.

One console with its telerobot over a 200 ms link (``teleprog up --delay-ms 200``) and one page
for the module; its tests are steps in turn (the drag comes first, while the camera still looks
at the tool where the console started). The session is read through GET requests only.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator

import pytest

from console_page import ConsolePage, wait_for
from support import PROJECT_DIR, RunningConsole, free_port, screenshot_if_failed, stop_process, wait_http

pytestmark = [pytest.mark.browser, pytest.mark.random_order(disabled=True)]

BANNER = "[data-regime-source]"
FIRST, SECOND = "DRIVE J1 TO 10 deg", "DRIVE J2 TO -50 deg"


@pytest.fixture(scope="module")
def regimes_console(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    """``teleprog up --delay-ms 200`` as conftest's ``linked_console`` starts it, given up to
    three minutes to answer (three processes start in turn on a busy machine)."""
    log_path = tmp_path_factory.mktemp("regimes") / "console.log"
    port = free_port()
    with log_path.open("w") as log:
        proc = subprocess.Popen([sys.executable, "-m", "server.cli", "up", "--port", str(port), "--delay-ms", "200"],
                                stdout=log, stderr=subprocess.STDOUT, cwd=PROJECT_DIR,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        wait_http(f"http://127.0.0.1:{port}/api/health", proc, timeout=180.0)
    except Exception:
        proc.kill()
        raise RuntimeError(f"console did not start:\n{log_path.read_text()}") from None
    running = RunningConsole(proc, port, log_path)
    yield running
    stop_process(proc)


@pytest.fixture(scope="module")
def module_ui(regimes_console, chromium) -> Iterator[ConsolePage]:
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    ui = ConsolePage(context.new_page(), regimes_console, quick_clicks=True)
    ui.open()
    ui.text_appears(r"Link: connected", timeout=30)
    yield ui
    context.close()


@pytest.fixture
def ui(module_ui: ConsolePage, request) -> Iterator[ConsolePage]:
    yield module_ui
    screenshot_if_failed(request, module_ui.page)


def choose(ui: ConsolePage, label: str, option: str) -> None:
    """Pick ``option`` in the dropdown ``label`` (``ConsolePage.choose_when_shown``)."""
    ui.choose_when_shown(label, option)


BANNER_JS = """() => {
  const e = document.querySelector("[data-regime-source]");
  return e && {regime: e.dataset.regime, source: e.dataset.regimeSource, streams: e.dataset.streams,
               text: e.innerText, colour: getComputedStyle(e).backgroundColor};
}"""


def banner(ui: ConsolePage) -> dict[str, str] | None:
    """The banner as the page shows it, read in one step (its element is replaced when it changes)."""
    return ui.page.evaluate(BANNER_JS)


def data(ui: ConsolePage, selector: str, key: str) -> str | None:
    """``dataset[key]`` of the first element matching ``selector`` now (None: none there)."""
    return ui.page.evaluate("([sel, key]) => { const e = document.querySelector(sel); return e ? e.dataset[key] : null; }",
                            [selector, key])


def banner_becomes(ui: ConsolePage, regime: str, source: str) -> dict[str, str]:
    return wait_for(lambda: (b := banner(ui)) and b["regime"] == regime and b["source"] == source and b,
                    timeout=30.0, what=f"banner {regime} ({source}); shown: {banner(ui)}")


def generation_on(ui: ConsolePage, on: bool = True) -> None:
    """Switch automatic generation on (or off) with its checkbox, wherever the page keeps it."""
    if ui.session()["program"]["auto_generate"] == on:
        return
    for tab in ("Drive", "Program"):
        ui.tab(tab)
        box = ui.page.get_by_label("Automatic generation", exact=True)
        if box.count() and box.first.is_visible():
            ui.press(box.first)  # quick_clicks: once visible (the panel re-renders as the link line ticks)
            break
    wait_for(lambda: ui.session()["program"]["auto_generate"] == on, what=f"automatic generation {'on' if on else 'off'}")


def test_the_banner_names_the_regime_what_it_does_and_who_chose_it(ui: ConsolePage) -> None:
    zone = ui.session()["regime"]["zone"]
    first = banner_becomes(ui, zone, "zone")
    assert "set by the zone" in first["text"]
    generation_on(ui, False)  # on from the start; off, the ONLINE banner says drags send nothing
    seen = {}
    for regime, words in (("operation", "SINGLE STEP (operation): one statement with its end condition"),
                          ("quasi", "OFFLINE (quasi-operation): preview, then send"),
                          ("free", "ONLINE (free zone): statements go to the robot as they are; "
                                   "automatic generation is off, so drags send nothing")):
        choose(ui, "Regime", regime)
        shown = banner_becomes(ui, regime, "override")
        assert words in shown["text"] and "the operator's override" in shown["text"], shown
        seen[regime] = shown["colour"]
    assert len(set(seen.values())) == 3, seen  # a colour each
    generation_on(ui)
    online = wait_for(lambda: (b := banner(ui)) and b["streams"] == "true" and b, timeout=30.0, what="banner: drags stream")
    assert "ONLINE (free zone): motions run on the robot as you drive" in online["text"]
    assert ui.page.locator(BANNER).first.is_visible()  # in the header, whatever tab is open
    ui.tab("Submit")
    assert ui.page.locator(BANNER).first.is_visible()


def test_a_drag_in_the_free_zone_says_it_runs_on_the_robot(ui: ConsolePage) -> None:
    ui.tab("Drive")
    indicator = ui.page.locator("[data-streaming]").first
    assert ui.session()["regime"]["regime"] == "free" and ui.session()["program"]["auto_generate"]
    sent_before = len(ui.session()["sent"]["items"])
    cx, cy = ui.canvas_center()
    for grab in (40, 55, 30, 70, 25):  # the gizmo's x arrow, as ConsolePage.drag_gizmo_x grabs it
        ui.page.mouse.move(cx + grab, cy)
        ui.settle()  # hovered before the press
        ui.page.mouse.down()
        ui.page.mouse.move(cx + grab + 70, cy, steps=14)
        try:
            wait_for(lambda: data(ui, "[data-streaming]", "streaming") == "true", timeout=5.0)
        except AssertionError:
            ui.page.mouse.up()
            continue
        assert "ONLINE: this drag runs on the robot as you drive" in indicator.inner_text()
        ui.page.mouse.up()
        break
    else:
        raise AssertionError("no grab point on the gizmo's x arrow started a drag")
    wait_for(lambda: len(ui.session()["sent"]["items"]) > sent_before, what="the drag's statements sent")
    ui.text_appears(r"Last drag sent [1-9]\d* statement\(s\) to the robot")
    assert data(ui, "[data-streaming]", "streaming") == "false"
    wait_for(lambda: ui.session()["sent"]["pending"] == 0, timeout=60.0, what="the drag's statements ran")


def test_submit_says_what_it_needs_and_preview_and_submit_sends(ui: ConsolePage) -> None:
    ui.reset_program()
    choose(ui, "Regime", "quasi")
    banner_becomes(ui, "quasi", "override")
    ui.insert_statements([FIRST])
    ui.tab("Submit")
    ui.text_appears(r"OFFLINE: statements 1 must be previewed to their end without warnings \(not yet previewed")
    assert data(ui, "[data-submit-ready]", "submitReady") == "false"
    # an instant preview confirms at once: the line says the range may go, and Submit sends it
    ui.tab("Preview")
    choose(ui, "Preview speed", "instant")
    wait_for(lambda: ui.session()["preview"]["speed"] == "instant", what="instant speed")
    ui.click("Start preview")
    ui.click("Play")
    wait_for(lambda: ui.session()["program"]["confirmed"] == [0, 1], what="the range confirmed")
    ui.click("End")
    ui.tab("Submit")
    ui.text_appears(r"Ready to send 1 \(OFFLINE")
    wait_for(lambda: data(ui, "[data-submit-ready]", "submitReady") == "true", what="the line says ready")
    sent = len(ui.session()["sent"]["items"])
    ui.submit_range(1, 1)
    wait_for(lambda: len(ui.session()["sent"]["items"]) == sent + 1, what=f"sent (notice {ui.notice()!r})")
    # two more at 10x in one click: previewed, then sent without another click
    ui.tab("Preview")
    choose(ui, "Preview speed", "10x")
    wait_for(lambda: ui.session()["preview"]["speed"] == 10.0, what="10x")
    ui.insert_statements(["DRIVE J1 TO 0 deg", SECOND])
    ui.tab("Submit")
    ui.text_appears(r"statements 1-2 must be previewed .*\(not yet previewed; Preview and submit previews 1-2")
    ui.text_appears(r"Preview and submit plays the range at 10x")
    ui.click("Preview and submit")
    wait_for(lambda: len(ui.session()["sent"]["items"]) == sent + 3, timeout=30,
             what=f"previewed and sent (notice {ui.notice()!r})")
    texts = [item["text"] for item in ui.session()["sent"]["items"][-3:]]
    assert texts == [FIRST, "DRIVE J1 TO 0 deg", SECOND]
    assert not ui.session()["preview"]["active"]
    ui.text_appears(r"OFFLINE: nothing to send: the program is empty")


def test_single_step_says_one_statement_with_its_end_condition(ui: ConsolePage) -> None:
    wait_for(lambda: ui.session()["sent"]["pending"] == 0, timeout=60.0, what="nothing pending")
    ui.reset_program()
    choose(ui, "Regime", "operation")
    banner_becomes(ui, "operation", "override")
    ui.insert_statements(["DRIVE J1 TO 5 deg", "DRIVE J1 TO 10 deg"])
    ui.tab("Submit")
    ui.text_appears(r"SINGLE STEP: one motion at a time, ended by its UNTIL condition or on a clear path; "
                    r"the previous one must be final \(one motion per step; statements 1 and 2 both move the arm")
    ui.click("Submit range")
    ui.text_appears(r"submit refused: operation regime: one motion per step; statements 1 and 2")  # the same words
