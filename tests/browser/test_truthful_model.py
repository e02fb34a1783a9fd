"""Issue 16, finding 1: the model tells the truth, checked from the page in headless Chromium
with a real telerobot behind a delayed link (``teleprog up --delay-ms 200``).

The steps are an operator's first peg transfer, in turn on one page:

* the legend names the ghost, in a colour of its own far from the virtual arm's;
* the robot's answers ("nothing to resume (robot idle)", "Robot confirmed STOP") go once the next
  move runs;
* a refused submit's notice goes with the next good submit; the notice log keeps both, newest
  first, with their level;
* after grasp and extract, the Drive readout stands where the robot holds the peg, not at home;
* with the peg seated in HOLE2 there is no collision to see, and the preview of a statement there
  says one thing, not "COLLISION at this moment" and "No warnings." at once.

The session's state is read through GET requests only, to check what the page shows.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

import numpy as np
import pytest
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from console_page import ConsolePage, option_name, wait_for
from e2e.test_console_session import PIECES
from support import RunningConsole, screenshot_if_failed, start_console, stop_process
from webui.ghost import GHOST_COLOR

# one page on one console for the module, its tests are steps an operator takes in turn: kept in their written order under --random-order
pytestmark = [pytest.mark.browser, pytest.mark.random_order(disabled=True)]

READOUT = re.compile(r"Tool \(world\): x (-?[\d.]+) mm, y (-?[\d.]+) mm, z (-?[\d.]+) mm(; holding (\w+))?")


@pytest.fixture(scope="module")
def truth_console(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("truth_page"), "--delay-ms", "200", timeout=180)
    yield running
    stop_process(running.proc)


@pytest.fixture(scope="module")
def ui(truth_console: RunningConsole, chromium) -> Iterator[ConsolePage]:
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    context.set_default_timeout(90_000)  # software WebGL on a loaded machine: a click may wait for frames
    page = ConsolePage(context.new_page(), truth_console, quick_clicks=True)
    try:
        page.open()
    except PlaywrightTimeout:  # a loaded machine can take longer than one wait to draw the first page
        page.open()
    yield page
    context.close()


@pytest.fixture(autouse=True)
def _screenshot(request, ui: ConsolePage) -> Iterator[None]:
    yield
    screenshot_if_failed(request, ui.page)


def choose_regime(ui: ConsolePage, value: str) -> None:
    """The status bar's Regime selector, its option clicked once it shows (software WebGL on a
    loaded machine keeps the sliding list from ever counting as "stable")."""
    ui.press(ui.row("Regime").locator("input").first)
    option = ui.page.get_by_role("option", name=option_name("Regime", value), exact=True).first
    option.wait_for(state="visible")
    ui.press(option)
    wait_for(lambda: ui.session()["regime"]["override"] == value, what=f"regime {value} chosen")


def _sent_count(ui: ConsolePage) -> int:
    return len(ui.console.api("GET", "/api/sent").json()["items"])


def send_piece(ui: ConsolePage, texts: list[str]) -> None:
    """Type the piece, submit it from the Submit tab, wait until the page shows it all done."""
    before = _sent_count(ui)
    ui.insert_statements(texts)
    ui.submit_range(1, len(texts))
    wait_for(lambda: len(ui.session()["program"]["entries"]) == 1, what=f"the piece left the program (notice {ui.notice()!r})")
    ui.wait_sent_final(before + len(texts))


def _rgb(text: str | None) -> np.ndarray:
    assert text is not None
    return np.array([int(v) for v in text.split(",")], dtype=float)


def test_the_legend_names_the_ghost_in_a_colour_of_its_own(ui: ConsolePage) -> None:
    ui.tab("Drive")
    ui.page.locator("[data-legend=ghost]").wait_for(state="attached", timeout=60_000)
    assert "remote arm (ghost)" in ui.page.locator("[data-legend-block]").inner_text()
    found = ui.page.eval_on_selector_all("[data-legend]", "els => els.map((e) => [e.dataset.legend, e.dataset.rgb])")
    swatches = {key: _rgb(rgb) for key, rgb in found}
    assert set(swatches) == {"virtual", "ghost", "path", "collision"}, swatches
    np.testing.assert_array_equal(swatches["ghost"], GHOST_COLOR)  # the colour the ghost is drawn in
    for other in ("virtual", "path", "collision"):  # far apart on the screen, not two greys
        assert np.linalg.norm(swatches["ghost"] - swatches[other]) > 150, (other, swatches)


def test_the_answer_to_stop_goes_once_the_robot_leaves_the_hold(ui: ConsolePage) -> None:
    api = ui.console.api
    ui.text_appears(r"Link: connected", timeout=60)
    wait_for(lambda: api("GET", "/api/link").json()["robot_state"] == "idle", 60, what="the robot idle")
    choose_regime(ui, "free")
    ui.click("STOP")  # an idle robot stops too: it holds until resumed
    ui.text_appears(r"Robot confirmed STOP after", timeout=30)
    wait_for(lambda: api("GET", "/api/link").json()["robot_state"] == "stopped", 30, what="the robot stopped")
    resume = ui.page.get_by_role("button", name="Resume", exact=True)
    ui.click("Resume")  # on: the robot holds
    wait_for(lambda: api("GET", "/api/link").json()["robot_state"] == "idle", 30, what="the robot idle again")
    # the answer to STOP is over once the robot left the hold, even with nothing to run, and
    # Resume is off: there is nothing to resume
    wait_for(lambda: "Robot confirmed STOP" not in ui.page.inner_text("body") and resume.is_disabled(), timeout=30,
             what="the STOP answer gone and Resume off on an idle robot")
    before = _sent_count(ui)
    ui.insert_statements(PIECES[0])  # above the peg, down to contact, grasp
    ui.submit_range(1, len(PIECES[0]))
    wait_for(lambda: any(s["status"] in ("running", "done") for s in api("GET", "/api/sent").json()["items"][before:]),
             timeout=45, what="the piece running after the resume")
    ui.wait_sent_final(before + len(PIECES[0]))


def test_a_refused_submit_goes_with_the_next_good_one_and_the_log_keeps_both(ui: ConsolePage) -> None:
    choose_regime(ui, "quasi")
    ui.insert_statements(PIECES[1])  # TASK extract_peg(peg, HOLE1)
    ui.submit_range(1, 1)
    wait_for(lambda: "submit refused" in ui.notice(), what="quasi-operation refusing an unpreviewed submit")
    choose_regime(ui, "free")
    ui.text_appears(r"Regime: \**ONLINE")
    assert "submit refused" in ui.notice()  # choosing a regime is no submit
    before = _sent_count(ui)
    ui.click("Submit range")
    wait_for(lambda: "submit refused" not in ui.notice(), what="the refusal gone after a good submit")
    ui.wait_sent_final(before + 1)
    ui.page.get_by_text("Notice log", exact=True).click()
    log = ui.page.locator("[data-notice-log]")
    log.wait_for(state="visible")
    text = log.inner_text()
    refused, resumed = text.find("submit refused"), text.find("robot applied resume")
    assert 0 <= refused < resumed, text  # newest first: the earlier test's resume further down
    assert re.search(r"\d\d:\d\d:\d\d\s+error\s+submit refused", text), text
    assert re.search(r"\d\d:\d\d:\d\d\s+info\s+robot applied resume", text), text


def test_after_grasp_and_extract_the_virtual_arm_holds_the_peg_where_the_robot_does(ui: ConsolePage) -> None:
    remote = wait_for(lambda: (r := ui.console.api("GET", "/api/remote").json())["state"] == "idle" and r["held"] == "peg" and r,
                      what="the robot at rest holding the peg")
    robot_mm = np.asarray(remote["world_T_tcp"])[:3, 3] * 1e3
    ui.tab("Drive")

    def readout() -> np.ndarray | None:
        m = READOUT.search(ui.page.inner_text("body"))
        return np.array([float(m.group(i)) for i in (1, 2, 3)]) if m and m.group(5) == "peg" else None

    shown = wait_for(lambda: (r := readout()) is not None and np.linalg.norm(r - robot_mm) < 5.0 and r.tolist(),
                     what=f"the Drive readout at the robot's tool {robot_mm.round(1)} mm holding the peg")
    peg_robot = np.asarray(remote["object_poses"]["peg"])[:3, 3]
    peg_virtual = np.asarray(ui.session()["arm"]["object_poses"]["peg"])[:3, 3]
    assert np.linalg.norm(peg_virtual - peg_robot) < 0.005, (shown, peg_virtual, peg_robot)


def test_a_peg_seated_in_hole2_is_no_collision_and_the_preview_says_one_thing(ui: ConsolePage) -> None:
    send_piece(ui, PIECES[2])  # carry it over HOLE2 and insert it in force mode
    ui.robot_end_taken()  # the insertion's end, within its tolerance, is taken from the robot
    send_piece(ui, PIECES[3])  # position mode, let go
    wait_for(lambda: ui.console.api("GET", "/api/remote").json()["held"] is None, what="the robot let go")
    ui.tab("Drive")
    ui.text_appears(r"Zone: ")
    wait_for(lambda: not ui.session()["collision"]["colliding"], what="no collision in the session")
    assert "COLLISION" not in ui.page.inner_text("body")
    ui.insert_statements(["MODE POSITION"])
    ui.tab("Preview")
    ui.click("Start preview")
    ui.text_appears(r"Statements 1-1: t = ")
    body = ui.page.inner_text("body")
    assert "COLLISION at this moment" not in body and "No warnings." in body, body
    ui.click("End")
    wait_for(lambda: not ui.session()["preview"]["active"], what="preview ended")
