"""The program list as an editor, in headless Chromium with mouse and keyboard only (issue 16,
finding 4): click a line to select it, shift-click a range, arrows, Delete a range, Ctrl+Z /
Ctrl+Shift+Z / Ctrl+Y, each refusal on its line (strict editing: the thesis's rules), each statement's planned duration, a submission
from the middle refused on its line, a sent list that pages.

One console (``teleprog up --delay-ms 200``: console, link and telerobot as processes) and one
page for the module; each test loads its program through the page's file upload and reads the
session through the API (reads only).
"""

from __future__ import annotations

import re

import pytest
from console_page import ConsolePage, wait_for
from support import screenshot_if_failed, start_console, stop_process

pytestmark = pytest.mark.browser

UP = "DRAW TO (0, -80, 200) mm IN WORK"
ACROSS = "DRAW TO (60, -80, 200) mm IN WORK"
BACK = "DRAW TO (30, -80, 200) mm IN WORK"
PAGE_S = 60.0  # s for the page to draw a change: software WebGL on a loaded machine draws slowly


@pytest.fixture(scope="module")
def linked_console(tmp_path_factory: pytest.TempPathFactory):
    """The console, its telerobot and a 200 ms link, as ``teleprog up`` starts them (given more
    time to start than the shared fixture: three processes on a loaded machine)."""
    running = start_console(tmp_path_factory.mktemp("editor"), "--delay-ms", "200", timeout=180.0)
    yield running
    stop_process(running.proc)


@pytest.fixture(scope="module")
def module_ui(linked_console, chromium):
    context = chromium.new_context(viewport={"width": 1400, "height": 1000})
    ui = ConsolePage(context.new_page(), linked_console, quick_clicks=True)
    ui.open()
    yield ui
    context.close()


@pytest.fixture
def ui(module_ui: ConsolePage, request) -> ConsolePage:
    yield module_ui
    screenshot_if_failed(request, module_ui.page)


def program(ui: ConsolePage) -> dict:
    return ui.session()["program"]


def texts(ui: ConsolePage) -> list[str]:
    """The session's statements as text (the trailing empty one left out)."""
    return [e["text"] for e in program(ui)["entries"][:-1]]


def drawn_texts(ui: ConsolePage) -> list[str]:
    """Every line of the page's program list, read in one go."""
    found = ui.page.locator("[data-program-list] [data-stmt-index]")
    return found.evaluate_all("els => els.map(e => e.textContent)")


def upload(ui: ConsolePage, *lines: str) -> None:
    """Send a program file holding ``lines`` through the page's upload button and wait until
    the session holds them and the page draws them (each line's text on its line)."""
    with ui.page.expect_file_chooser() as chooser:
        ui.click("Load program file")
    text = "".join(line + "\n" for line in lines) or "# nothing\n"
    chooser.value.set_files(files=[{"name": "editor.tp", "mimeType": "text/plain", "buffer": text.encode()}])
    wait_for(lambda: texts(ui) == list(lines), what="program loaded")

    def drawn() -> bool:
        shown = drawn_texts(ui)
        return len(shown) == len(lines) + 1 and all(want in got for want, got in zip(lines, shown))

    wait_for(drawn, timeout=PAGE_S, what="the page draws the loaded program")


def load(ui: ConsolePage, *lines: str) -> None:
    """Load a program file holding ``lines`` through the page's upload button. When the
    session already holds the same program (the tests reuse one), an empty one goes first:
    otherwise the waits would pass on the old program and the page could replace its list
    under the test's next click."""
    if ui.session()["preview"]["active"]:
        ui.tab("Preview")
        ui.click("End")
        wait_for(lambda: not ui.session()["preview"]["active"], what="preview ended")
    ui.tab("Program")
    if lines and texts(ui) == list(lines):
        upload(ui)
    upload(ui, *lines)


def line(ui: ConsolePage, index: int):
    """The program list's line of entry ``index`` (0-based), as the page draws it."""
    return ui.page.locator(f'[data-program-list] [data-stmt-index="{index}"]')


def click_line(ui: ConsolePage, index: int, shift: bool = False) -> None:
    """A mouse click on a line (with Shift held for a range); see ``ConsolePage.quick_clicks``."""
    ui.click_program_line(index, shift, timeout=PAGE_S)


def selected_lines(ui: ConsolePage) -> list[int]:
    """The lines drawn selected, read in one go: counting them and then reading each one lets
    the list re-render in between, and an element gone by then is waited for until a timeout."""
    found = ui.page.locator('[data-program-list] [data-selected="true"]')
    return found.evaluate_all("els => els.map(e => Number(e.getAttribute('data-stmt-index')))")


def range_is(ui: ConsolePage, first: int, last: int) -> None:
    wait_for(lambda: program(ui)["selected_range"] == [first, last], what=f"entries {first}..{last} selected")
    wait_for(lambda: selected_lines(ui) == list(range(first, last + 1)), timeout=PAGE_S,
             what=f"lines {first}..{last} drawn selected")


def test_click_and_shift_click_select_lines_and_a_range(ui: ConsolePage) -> None:
    load(ui, UP, "SPEED 50 %", "SPEED 20 %", ACROSS)
    click_line(ui, 1)
    range_is(ui, 1, 1)
    ui.text_appears(r"▶ 2: SPEED 50", timeout=PAGE_S)
    click_line(ui, 3, shift=True)
    range_is(ui, 1, 3)
    assert program(ui)["selected"] == 3  # the cursor is where the range was extended to


def test_arrows_delete_and_undo_redo_from_the_keyboard(ui: ConsolePage) -> None:
    load(ui, UP, "SPEED 50 %", "SPEED 20 %", ACROSS)
    click_line(ui, 0)
    range_is(ui, 0, 0)
    keys = ui.page.keyboard
    keys.press("ArrowDown")
    range_is(ui, 1, 1)
    keys.press("Shift+ArrowDown")
    range_is(ui, 1, 2)
    keys.press("Delete")  # two parameter statements from the middle: allowed, one step
    wait_for(lambda: [e["kind"] for e in program(ui)["entries"]] == ["DRAW", "DRAW", "EMPTY"], what="range deleted")
    assert program(ui)["selected"] == 1  # the statement after the range, not the empty line
    keys.press("Control+z")
    wait_for(lambda: len(program(ui)["entries"]) == 5, what="the range back in one undo")
    range_is(ui, 1, 2)
    keys.press("Control+Shift+z")
    wait_for(lambda: len(program(ui)["entries"]) == 3, what="redo with Ctrl+Shift+Z")
    keys.press("Control+z")
    wait_for(lambda: len(program(ui)["entries"]) == 5, what="undone again")
    keys.press("Control+y")
    wait_for(lambda: len(program(ui)["entries"]) == 3, what="redo with Ctrl+Y")


def strict_editing(ui: ConsolePage, on: bool) -> None:
    """Tick or clear the Program tab's "Strict editing" box (the thesis's rules; free editing is
    the default and has its own page test, ``test_free_editing_page.py``)."""
    if program(ui)["strict_editing"] != on:
        ui.page.get_by_label("Strict editing (thesis rules)", exact=True).click()
    wait_for(lambda: program(ui)["strict_editing"] is on, what=f"strict editing {'on' if on else 'off'}")


def test_a_refused_range_delete_is_shown_on_its_line(ui: ConsolePage) -> None:
    load(ui, UP, "SPEED 50 %", ACROSS, BACK)
    strict_editing(ui, True)
    try:
        click_line(ui, 1)
        click_line(ui, 2, shift=True)
        range_is(ui, 1, 2)
        ui.page.keyboard.press("Delete")
        refusal = ui.page.locator('[data-program-list] [data-refusal-for="2"]')  # under the DRAW at 3
        refusal.wait_for(timeout=PAGE_S * 1000)
        assert "action continuity" in refusal.inner_text()
        assert refusal.get_attribute("title") == "rule delete.action-not-last"  # the id in the tooltip only
        assert "delete.action-not-last" not in refusal.inner_text()
        assert line(ui, 2).get_attribute("data-refused") == "true"
        assert len(program(ui)["entries"]) == 5  # nothing deleted
        # the range that reaches the end goes, in one step; the refusal leaves with the change
        click_line(ui, 4, shift=True)
        range_is(ui, 1, 4)
        ui.page.keyboard.press("Delete")
        wait_for(lambda: [e["text"] for e in program(ui)["entries"][:-1]] == [UP], what="statements 2..4 deleted")
        ui.page.locator("[data-program-list] [data-refusal-for]").wait_for(state="detached", timeout=PAGE_S * 1000)
    finally:
        strict_editing(ui, False)


def test_each_line_shows_its_planned_duration(ui: ConsolePage) -> None:
    load(ui, UP, "SPEED 50 %", ACROSS)
    entries = wait_for(lambda: (e := program(ui)["entries"]) and e[0]["duration_s"] and e, what="durations")
    for entry in entries[:-1]:
        shown = line(ui, entry["index"]).locator("[data-duration]")
        text = f"{entry['duration_s']:.1f} s"
        wait_for(lambda shown=shown, text=text: shown.inner_text() == text, timeout=PAGE_S, what=f"duration of line {entry['index'] + 1}")
    assert entries[0]["duration_s"] > 0.1 and entries[1]["duration_s"] == 0.0


def test_a_submission_from_the_middle_is_refused_on_its_line(ui: ConsolePage) -> None:
    load(ui, UP, ACROSS)
    ui.submit_range(2, 2)
    wait_for(lambda: (r := program(ui)["refusal"]) and r["rule"] == "submit.prefix" and r["index"] == 1,
             what="the submit refusal on statement 2")
    ui.tab("Program")
    refusal = ui.page.locator('[data-program-list] [data-refusal-for="1"]')
    refusal.wait_for(timeout=PAGE_S * 1000)
    assert "submit 1..2 instead" in refusal.inner_text()
    assert len(program(ui)["entries"]) == 3  # nothing left the program


def test_the_sent_list_pages_to_its_oldest_entries(ui: ConsolePage) -> None:
    before = len(ui.session()["sent"]["items"])
    count = 16
    load(ui, *[f"SPEED {10 + i} %" for i in range(count)])
    ui.choose("Regime", "free")
    wait_for(lambda: ui.session()["regime"]["regime"] == "free", what="free regime")
    ui.submit_range(1, count)
    total = before + count
    ui.text_appears(rf"\b{total} sent, 0 pending", timeout=PAGE_S)
    pages = -(-total // 14)
    ui.text_appears(rf"Page 1 of {pages} \(newest\): sent {total - 13}-{total} of {total}", timeout=PAGE_S)
    for _ in range(pages - 1):
        ui.click("Older")
    shown = ui.text_appears(rf"Page {pages} of {pages} \(oldest\): sent 1-\d+ of {total}", timeout=PAGE_S)
    assert re.search(r"sent 1-", shown)
    body = ui.page.inner_text("body")
    assert re.search(r"^#1 SPEED", body, re.MULTILINE), "the oldest sent statement is reachable"
    ui.click("Newer")
    if pages > 2:
        ui.text_appears(rf"Page {pages - 1} of {pages}", timeout=PAGE_S)
    else:
        ui.text_appears(rf"Page 1 of {pages} \(newest\)", timeout=PAGE_S)
