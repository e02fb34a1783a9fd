"""The Trials folder on the Submit tab (issue 19, point 6): the operator opens it, picks a trial,
its runs and its delay, starts it, and reads the table and the plots when the progress bar is
full; the page's batch is the one ``GET /api/trials/{id}`` reports. Driven with mouse and keyboard
only. (A folder, not a sixth tab: six tabs wrap the tab strip onto a second row.)"""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
from playwright.sync_api import TimeoutError as PlaywrightTimeout
from console_page import ConsolePage, wait_for
from support import RunningConsole, screenshot_if_failed, start_console, stop_process

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def console(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("trials_page"), "--delay-ms", "100", "--no-record")
    yield running
    stop_process(running.proc)


@pytest.fixture
def ui(console: RunningConsole, chromium, request) -> Iterator[ConsolePage]:
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    page = ConsolePage(context.new_page(), console, quick_clicks=True)
    page.open()
    yield page
    screenshot_if_failed(request, page.page)
    context.close()


def test_a_grasp_trial_started_on_the_submit_tab_shows_its_table_and_plots(ui: ConsolePage) -> None:
    ui.tab("Submit")
    rows = {round(ui.page.get_by_role("tab", name=n).bounding_box()["y"]) for n in ("Drive", "Program", "Preview", "Submit", "Task")}
    assert len(rows) == 1, f"the tab strip wrapped: tabs at y = {sorted(rows)}"
    folder = ui.page.get_by_text("Trials (virtual time)", exact=True)
    body = ui.page.locator('[data-trial-state="none"]')
    for _ in range(3):  # under load a press on the folder's title can land before the tab is laid out
        folder.scroll_into_view_if_needed()
        ui.press(folder)
        try:
            body.wait_for(state="visible", timeout=10_000)
            break
        except PlaywrightTimeout:
            continue
    body.wait_for(state="visible", timeout=15_000)
    ui.page.locator('[data-trial-state="none"]').scroll_into_view_if_needed()  # the folder is at the tab's foot
    time.sleep(0.5)  # the folder has slid open
    ui.choose("Trial kind", "grasp")
    ui.set_number("Runs per mode", 2)
    ui.set_number("Trial delay (ms)", 300)
    ui.click("Start trial")
    done = ui.page.locator('[data-trial-state="done"]')
    done.wait_for(state="visible", timeout=180_000)
    batch_id = int(done.get_attribute("data-trial-id"))
    table = ui.page.locator("[data-trial-table]").inner_text()
    assert "offline" in table and "100 %" in table
    api = ui.console.api("GET", f"/api/trials/{batch_id}").json()
    assert api["state"] == "done" and api["request"]["kind"] == "grasp" and api["request"]["runs"] == 2
    assert api["request"]["delay_ms"] == 300 and api["summary"]["modes"][0]["succeeded"] == 2
    wait_for(lambda: ui.page.locator("img").count() >= 2, timeout=20, what="the two plots on the tab")
