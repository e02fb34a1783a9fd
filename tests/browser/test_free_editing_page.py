"""Free editing from the page (issue 37), in headless Chromium with mouse and keyboard only: three
DRAW statements in the editor, a click on the middle one and Delete take it out, the other two are
re-planned (each shows its planned duration) with no error anywhere on the list, and Ctrl+Z brings
it back; ArrowDown on the trailing empty line raises nothing; with the "Strict editing" box ticked
the thesis's rule refuses the same delete in plain words on the line (the rule's id only in the
line's tooltip).

One console (``teleprog up --no-robot``: editing needs no robot) and one page for the module; the
program goes in through the page's file upload; the session is read through the API (reads only).
"""

from __future__ import annotations

import pytest
from console_page import ConsolePage, wait_for
from support import screenshot_if_failed, start_console, stop_process

pytestmark = pytest.mark.browser

UP = "DRAW TO (0, -80, 200) mm IN WORK"
ACROSS = "DRAW TO (60, -80, 200) mm IN WORK"
BACK = "DRAW TO (30, -80, 200) mm IN WORK"
PAGE_S = 60.0  # s for the page to draw a change: software WebGL on a loaded machine draws slowly
LIST = "[data-program-list]"


@pytest.fixture(scope="module")
def lone_console(tmp_path_factory: pytest.TempPathFactory):
    running = start_console(tmp_path_factory.mktemp("free-editing"), "--no-robot", timeout=180.0)
    yield running
    stop_process(running.proc)


@pytest.fixture(scope="module")
def module_ui(lone_console, chromium):
    context = chromium.new_context(viewport={"width": 1400, "height": 1000})
    ui = ConsolePage(context.new_page(), lone_console, quick_clicks=True)
    ui.open()
    ui.tab("Program")
    yield ui
    context.close()


@pytest.fixture
def ui(module_ui: ConsolePage, request) -> ConsolePage:
    yield module_ui
    screenshot_if_failed(request, module_ui.page)


def program(ui: ConsolePage) -> dict:
    return ui.session()["program"]


def texts(ui: ConsolePage) -> list[str]:
    return [e["text"] for e in program(ui)["entries"][:-1]]


def drawn(ui: ConsolePage) -> list[str]:
    """Every line of the page's program list, read in one go."""
    return ui.page.locator(f"{LIST} [data-stmt-index]").evaluate_all("els => els.map(e => e.textContent)")


def drawn_durations(ui: ConsolePage) -> list[str]:
    return ui.page.locator(f"{LIST} [data-stmt-index] [data-duration]").evaluate_all("els => els.map(e => e.textContent)")


def refusals_drawn(ui: ConsolePage) -> int:
    return ui.page.locator(f"{LIST} [data-refusal-for]").count()


def shows(ui: ConsolePage, lines: list[str]) -> bool:
    """The page's list holds exactly ``lines`` and the trailing empty one, in order."""
    shown = drawn(ui)
    return len(shown) == len(lines) + 1 and all(want in got for want, got in zip(lines, shown))


def load(ui: ConsolePage, *lines: str) -> None:
    """Send a program file holding ``lines`` through the page's upload button; wait until the
    session holds them and the page draws them."""
    if lines and texts(ui) == list(lines):
        load(ui)  # the same program already: an empty one first, so the waits see the new one
    with ui.page.expect_file_chooser() as chooser:
        ui.click("Load program file")
    text = "".join(line + "\n" for line in lines) or "# nothing\n"
    chooser.value.set_files(files=[{"name": "three.tp", "mimeType": "text/plain", "buffer": text.encode()}])
    wait_for(lambda: texts(ui) == list(lines), what="program loaded")
    wait_for(lambda: shows(ui, list(lines)), timeout=PAGE_S, what="the page draws the loaded program")


def click_line(ui: ConsolePage, index: int) -> None:
    ui.click_program_line(index, timeout=PAGE_S)


def selected_is(ui: ConsolePage, index: int) -> None:
    wait_for(lambda: program(ui)["selected_range"] == [index, index], what=f"entry {index} selected")
    wait_for(lambda: ui.page.locator(f'{LIST} [data-cursor="true"]').get_attribute("data-stmt-index") == str(index),
             timeout=PAGE_S, what=f"line {index} drawn as the cursor")


def strict_box(ui: ConsolePage):
    return ui.page.get_by_label("Strict editing (thesis rules)", exact=True)


def set_strict(ui: ConsolePage, on: bool) -> None:
    if program(ui)["strict_editing"] != on:
        strict_box(ui).click()
    wait_for(lambda: program(ui)["strict_editing"] is on, what=f"strict editing {'on' if on else 'off'}")


def test_delete_the_middle_draw_then_undo(ui: ConsolePage) -> None:
    set_strict(ui, False)  # the default
    load(ui, UP, ACROSS, BACK)
    wait_for(lambda: all(d.endswith(" s") for d in drawn_durations(ui)[:3]), timeout=PAGE_S, what="three durations drawn")
    click_line(ui, 1)
    selected_is(ui, 1)
    ui.page.keyboard.press("Delete")
    wait_for(lambda: texts(ui) == [UP, BACK], what="the middle DRAW deleted")
    wait_for(lambda: shows(ui, [UP, BACK]), timeout=PAGE_S, what="the page draws two statements")
    view = program(ui)
    assert view["refusal"] is None
    assert all(e["duration_s"] and e["duration_s"] > 0 for e in view["entries"][:-1])  # both re-planned
    wait_for(lambda: all(d.endswith(" s") for d in drawn_durations(ui)[:2]), timeout=PAGE_S, what="two durations drawn")
    assert refusals_drawn(ui) == 0
    assert 'data-refused="true"' not in ui.page.locator(LIST).inner_html()
    ui.page.keyboard.press("Control+z")
    wait_for(lambda: texts(ui) == [UP, ACROSS, BACK], what="undo restores the DRAW")
    wait_for(lambda: shows(ui, [UP, ACROSS, BACK]), timeout=PAGE_S, what="the page draws three statements again")
    selected_is(ui, 1)


def test_arrow_down_on_the_trailing_line_raises_nothing(ui: ConsolePage) -> None:
    load(ui, UP, ACROSS)
    click_line(ui, 2)  # the trailing empty statement
    selected_is(ui, 2)
    ui.page.keyboard.press("ArrowDown")
    ui.page.keyboard.press("ArrowUp")  # a key after it, so the wait below knows the first was handled
    selected_is(ui, 1)
    assert program(ui)["refusal"] is None and refusals_drawn(ui) == 0
    assert "select.range" not in ui.page.inner_text("body")


def test_strict_editing_refuses_in_plain_words_with_the_rule_in_the_tooltip(ui: ConsolePage) -> None:
    load(ui, UP, ACROSS, BACK)
    set_strict(ui, True)
    try:
        click_line(ui, 1)
        selected_is(ui, 1)
        ui.page.keyboard.press("Delete")
        refusal = ui.page.locator(f'{LIST} [data-refusal-for="1"]')
        refusal.wait_for(timeout=PAGE_S * 1000)
        assert refusal.get_attribute("title") == "rule delete.action-not-last"
        text = refusal.inner_text()
        assert "action continuity" in text and "delete.action-not-last" not in text and "rule" not in text
        assert texts(ui) == [UP, ACROSS, BACK]  # nothing deleted
    finally:
        set_strict(ui, False)
