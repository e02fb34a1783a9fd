"""Driving the console page the way an operator does: mouse clicks, typing, dragging.

Every helper acts on visible page elements (tabs, buttons, labelled inputs, the 3D canvas); the
tests read results from the page's text and check them against the API's state. Nothing here
calls an endpoint that changes the session.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from typing import TypeVar

from playwright.sync_api import Locator, Page
from playwright.sync_api import TimeoutError as PlaywrightTimeout

T = TypeVar("T")


def wait_for(predicate: Callable[[], T], timeout: float = 15.0, interval: float = 0.1, what: str = "condition") -> T:
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"{what} not met within {timeout:g} s")
        time.sleep(interval)


class ConsolePage:
    def __init__(self, page: Page, console) -> None:
        self.page = page
        self.console = console

    # -- reading the session (checks only) -------------------------------------------------
    def session(self) -> dict:
        return self.console.api("GET", "/api/session").json()

    # -- page --------------------------------------------------------------------------------
    def open(self) -> None:
        self.page.goto(self.console.url + "/")
        self.page.wait_for_selector("canvas", timeout=30_000)
        self.page.get_by_role("button", name="STOP").wait_for(timeout=30_000)
        self.dismiss_notices(wait=15.0)

    def dismiss_notices(self, wait: float = 0.0) -> None:
        """Close the browser's own notices (e.g. "software WebGL rendering"): they cover the
        top left of the 3D view. Waits up to ``wait`` s for one to show first."""
        notice = self.page.locator(".mantine-Notification-root")
        try:
            notice.first.wait_for(timeout=max(wait, 0.01) * 1000)
        except PlaywrightTimeout:
            return
        buttons = self.page.locator(".mantine-Notification-closeButton")
        for i in range(buttons.count()):
            try:
                buttons.nth(i).click(timeout=1_000, force=True)  # it slides in: never "stable"
            except PlaywrightTimeout:
                pass  # closed by itself or covered: a notice is cosmetic

    def tab(self, name: str) -> None:
        self.page.get_by_role("tab", name=name).click()

    def click(self, label: str) -> None:
        self.page.get_by_role("button", name=label, exact=True).first.click()

    def row(self, label: str) -> Locator:
        """The GUI row whose label reads exactly ``label`` (viser puts label and input in one
        flex row; text inputs are not tied to their label by id)."""
        label_el = self.page.locator("label", has_text=re.compile(rf"^{re.escape(label)}$"))
        return self.page.locator(".mantine-Flex-root", has=label_el).last

    def type_into(self, label: str, text: str) -> None:
        box = self.row(label).locator("input").first
        box.click()
        box.press("Control+a")
        box.press("Delete")
        box.type(text)

    def choose(self, label: str, option: str, exact: bool = True) -> None:
        self.row(label).locator("input").first.click()
        self.page.get_by_role("option", name=option, exact=exact).first.click()

    def set_number(self, label: str, value: float) -> None:
        """Type into a number input (or a slider's number box) and press Enter."""
        box = self.number_box(label)
        box.click()
        box.press("Control+a")
        box.type(f"{value:g}")
        box.press("Enter")

    def number_box(self, label: str) -> Locator:
        return self.row(label).locator("input:not([type=hidden])").last

    def text_appears(self, pattern: str, timeout: float = 15.0) -> str:
        """Wait until the page's text matches ``pattern`` (a regex); return the match."""
        regex = re.compile(pattern)

        def found() -> str | None:
            m = regex.search(self.page.inner_text("body"))
            return m.group(0) if m else None

        return wait_for(found, timeout, what=f"text /{pattern}/ on the page")

    def canvas_center(self) -> tuple[float, float]:
        box = self.page.locator("canvas").first.bounding_box()
        assert box is not None
        return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2

    def drag(self, x0: float, y0: float, x1: float, y1: float, steps: int = 12) -> None:
        self.page.mouse.move(x0, y0)
        time.sleep(0.15)
        self.page.mouse.down()
        self.page.mouse.move(x1, y1, steps=steps)
        time.sleep(0.1)
        self.page.mouse.up()

    def drag_gizmo_x(self, pixels: float) -> list[float]:
        """Grab the gizmo's x arrow (the camera looks at the tool from -y, so world x points
        right from the canvas centre) and pull it ``pixels`` to the right; returns the tool
        position (mm) after the first grab that moved it."""
        before = self.session()["arm"]["tool_xyz_mm"]
        cx, cy = self.canvas_center()
        for grab in (40, 55, 30, 70, 25):
            self.drag(cx + grab, cy, cx + grab + pixels, cy)
            time.sleep(0.4)
            after = self.session()["arm"]["tool_xyz_mm"]
            if abs(after[0] - before[0]) > 1.0:
                return after
        raise AssertionError("no grab point on the gizmo's x arrow moved the tool")

    def reset_program(self) -> None:
        """Start from an empty program, as an operator would: end a running preview, then load
        a program file holding no statements."""
        if self.session()["preview"]["active"]:
            self.tab("Preview")
            self.click("End")
            wait_for(lambda: not self.session()["preview"]["active"], what="preview ended")
        self.tab("Program")
        with self.page.expect_file_chooser() as chooser:
            self.click("Load program file")
        chooser.value.set_files(files=[{"name": "empty.tp", "mimeType": "text/plain", "buffer": b"# nothing yet\n"}])
        wait_for(lambda: len(self.session()["program"]["entries"]) == 1, what="empty program loaded")

    def insert_statement(self, text: str) -> None:
        self.tab("Program")
        self.type_into("New statement", text)
        self.click("Insert before selection")
