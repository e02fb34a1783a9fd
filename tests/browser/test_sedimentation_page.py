"""The sedimentation view (``teleprog up --sedimentation``) in headless Chromium: the status line
shows the method and its FPS, and the controls driven with keyboard and mouse change the running
simulation (read back from ``GET /api/sedimentation``; the page alone makes each change)."""

from __future__ import annotations

import re
import time
from collections.abc import Iterator

import pytest
from playwright.sync_api import Locator, Page

import support
from support import RunningConsole, start_console, stop_process

pytestmark = pytest.mark.browser

STATUS = re.compile(r"Method (\w+) · FPS ([\d,.]+) · pairs ([\d,]+) · frame ([\d,]+)")


@pytest.fixture(scope="module")
def sedimentation(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("sedimentation"), "--sedimentation")
    yield running
    stop_process(running.proc)


def wait_for(predicate, timeout: float = 20.0, what: str = "condition"):
    return support.wait_for(predicate, timeout, 0.1, what)


def status(page: Page) -> re.Match | None:
    return STATUS.search(page.inner_text("body"))


def row(page: Page, label: str) -> Locator:
    """The GUI row whose label reads exactly ``label`` (viser puts label and input in one row)."""
    label_el = page.locator("label", has_text=re.compile(rf"^{re.escape(label)}$"))
    return page.locator(".mantine-Flex-root", has=label_el).last


def test_page_shows_method_fps_and_follows_keyboard_and_mouse(sedimentation: RunningConsole, page: Page) -> None:
    api = lambda: sedimentation.api("GET", "/api/sedimentation").json()  # noqa: E731 - reading only
    start = api()
    assert "teleprog console: open http://127.0.0.1:" in sedimentation.log_path.read_text()
    page.goto(sedimentation.url + "/")
    page.wait_for_selector("canvas", timeout=30_000)
    shown = wait_for(lambda: (m := status(page)) and float(m.group(2).replace(",", "")) > 0 and m,
                     30.0, "a status line with a positive FPS")
    assert shown.group(1) == start["method"] == "usscd"
    assert f"N {start['n']:,}" in page.inner_text("body")

    # keyboard: type a new N into its box
    box = row(page, "N (bodies)").locator("input:not([type=hidden])").last
    box.click()
    box.press("Control+a")
    box.type("750")
    box.press("Enter")
    state = wait_for(lambda: (s := api())["n"] == 750 and s, what="N = 750 in the API")
    assert state["method"] == "usscd" and state["size"] == pytest.approx((750 / state["density"]) ** (1 / 3))
    wait_for(lambda: "N 750 ·" in page.inner_text("body"), what="N 750 on the page")

    # mouse: pick another method from the dropdown
    row(page, "Method").locator("input").first.click()
    page.get_by_role("option", name="scd", exact=True).first.click()
    wait_for(lambda: api()["method"] == "scd", what="method scd in the API")
    wait_for(lambda: (m := status(page)) and m.group(1) == "scd", what="method scd on the page")
    assert api()["n"] == 750

    # mouse: pause, and the frame counter stops
    page.get_by_role("button", name="Pause").click()
    paused = wait_for(lambda: (s := api())["paused"] and s, what="paused in the API")
    page.get_by_role("button", name="Resume").wait_for(timeout=10_000)
    time.sleep(0.3)
    assert api()["frame"] == paused["frame"]

    # a refused value: the page says why, the simulation keeps its N
    box.click()
    box.press("Control+a")
    box.type("1")
    box.press("Enter")
    wait_for(lambda: "Refused: N (number of bodies) must be in [2," in page.inner_text("body"), what="the refusal")
    assert api()["n"] == 750

    # a change made elsewhere (a second operator's page) shows in this page's controls
    other = page.context.new_page()
    try:
        other.goto(sedimentation.url + "/")
        other.wait_for_selector("canvas", timeout=30_000)
        other_box = row(other, "N (bodies)").locator("input:not([type=hidden])").last
        wait_for(lambda: other_box.input_value().replace(",", "") == "750", what="N 750 in the second page")
        other_box.click()
        other_box.press("Control+a")
        other_box.type("900")
        other_box.press("Enter")
        wait_for(lambda: api()["n"] == 900, what="N = 900 in the API")
    finally:
        other.close()
    wait_for(lambda: box.input_value().replace(",", "") == "900", what="N box following the other page")
    wait_for(lambda: "N 900 ·" in page.inner_text("body"), what="N 900 on the page")
