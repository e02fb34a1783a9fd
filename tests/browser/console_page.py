"""Driving the console page the way an operator does: mouse clicks, typing, dragging.

Every helper acts on visible page elements (tabs, buttons, labelled inputs, the 3D canvas); the
tests read results from the page's text and check them against the API's state. Nothing here
calls an endpoint that changes the session.
"""

from __future__ import annotations

import re
import time

from playwright.sync_api import Error as PlaywrightError
from playwright.sync_api import Locator, Page
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from support import DRAG_EFFECT_S, PAGE_DPR, PAGE_WAIT_S, wait_for  # noqa: F401 - the page tests import wait_for from here too

def option_name(label: str, option: str) -> str:
    """The text of a dropdown's option for ``option``: the Regime selector names a regime in the
    operator's words (``free`` -> ``ONLINE (free zone)``); other selectors show their values."""
    from webui.status_bar import regime_option

    return regime_option(option) if label == "Regime" else option


GIZMO_X_GRABS_PX = (40, 55, 30, 70, 25)
"""Where, right of the canvas centre, the tool camera shows the gizmo's x arrow: the first almost
always; the others only after a drag there moved nothing."""
HAND_S = 0.15  # s between two quick clicks, more than viser's 50 ms GUI message throttle
ENABLED_S = PAGE_WAIT_S  # s for the page to turn a control on (it follows the link, 4 updates a second)
TWO_FRAMES_JS = "() => new Promise(done => requestAnimationFrame(() => requestAnimationFrame(() => done(true))))"
"""Resolves once the page has drawn twice: the pointer events before it are handled (raycast, hover)."""

# Pointer moves dispatched on the 3D canvas at a fixed rate, a sine sweep along x: the page's own
# pointer handling (three.js raycasting in drei's PivotControls), its throttled sender and
# WebSocket worker all run as for a real mouse. Headless Chromium hands real mouse moves to the
# page once per drawn frame, and draws in software here (a few frames a second), so this is how a
# test or benchmark feeds the page at a display's rate. Returns the dispatch times (page clock, ms).
POINTER_SWEEP_JS = """([x0, y, amplitude, hz, seconds, period, all]) => new Promise((done) => {
  const canvas = [...document.querySelectorAll("canvas")].find((c) => c.width > 0 && c.clientWidth > 300);
  const t0 = performance.now(); const times = [];
  const fire = () => {
    const now = performance.now(); const t = (now - t0) / 1000;
    if (all ? times.length >= Math.round(hz * seconds) : t >= seconds) { done(times); return; }
    canvas.dispatchEvent(new PointerEvent("pointermove", {
      clientX: x0 + amplitude * Math.sin(2 * Math.PI * t / period), clientY: y, pointerId: 1,
      pointerType: "mouse", isPrimary: true, buttons: 1, bubbles: true, cancelable: true}));
    times.push(now);
    setTimeout(fire, Math.max(0, t0 + times.length * 1000 / hz - performance.now()));
  };
  fire();
})"""


class ConsolePage:
    def __init__(self, page: Page, console, quick_clicks: bool = False) -> None:
        self.page = page
        self.console = console
        # Playwright waits before each click until the element has kept its place for two
        # animation frames; when software WebGL on a loaded machine stretches frames to a second,
        # that wait dominates. ``quick_clicks`` clicks static controls once they are visible,
        # after a pause as long as a hand takes to reach them: viser's page sends GUI messages
        # through one sender throttled to 50 ms that keeps only the latest message, so a click
        # within 50 ms of the last keystroke would replace the typed value on its way out.
        self.quick_clicks = quick_clicks

    # -- reading the session (checks only) -------------------------------------------------
    def session(self) -> dict:
        return self.console.api("GET", "/api/session").json()

    # -- page --------------------------------------------------------------------------------
    def open(self, query: str = "", camera: str = "tool") -> None:
        """Open the console's page; ``query`` (e.g. ``"fixedDpr=0.1"``) goes to viser's page, which
        draws at ``support.PAGE_DPR`` unless the query says otherwise.
        ``camera="tool"``: the page starts looking at the tool from ``CAMERA_OFFSET`` (the
        terrain's offset in a terrain cell), world x to the right, so the gizmo's handles lie
        where ``drag_gizmo_x`` and the tests' projections expect them; ``"default"``: the
        console's own camera, which frames the cell's work (``shared.cells.framing``)."""
        if camera == "tool":
            query = "&".join(q for q in (query, self.tool_camera_query()) if q)
        if "fixedDpr=" not in query:
            query = "&".join(q for q in (query, f"fixedDpr={PAGE_DPR}") if q)
        self.page.goto(self.console.url + "/viser/?" + query)
        self.page.wait_for_selector("canvas", timeout=PAGE_WAIT_S * 1000)
        self.page.get_by_role("button", name="STOP").wait_for(timeout=PAGE_WAIT_S * 1000)
        self.dismiss_notices(wait=15.0)

    def tool_camera_query(self) -> str:
        """viser's URL parameters for a camera looking at the tool as it stands now from
        ``CAMERA_OFFSET`` (``TERRAIN_CAMERA_OFFSET`` where the cell has a terrain)."""
        from webui.console import CAMERA_OFFSET, TERRAIN_CAMERA_OFFSET

        tool = [row[3] for row in self.session()["arm"]["world_T_tcp"][:3]]
        terrain = self.console.api("GET", "/api/terrain").status_code == 200
        offset = TERRAIN_CAMERA_OFFSET if terrain else CAMERA_OFFSET
        eye = [t + o for t, o in zip(tool, offset)]
        return "initialCameraPosition={}&initialCameraLookAt={}".format(
            ",".join(f"{v:.6f}" for v in eye), ",".join(f"{v:.6f}" for v in tool))

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

    def press(self, target: Locator) -> None:
        """A mouse click on ``target`` (see ``quick_clicks``)."""
        if self.quick_clicks:
            target.wait_for(state="visible")
            # a forced click skips Playwright's wait for an enabled control: wait for it here (a
            # button the page turns on with the next link update, e.g. Resume once the robot holds)
            wait_for(target.is_enabled, timeout=ENABLED_S, interval=0.05, what="the control enabled")
            time.sleep(HAND_S)
            target.click(force=True)
        else:
            target.click()

    def click_program_line(self, index: int, shift: bool = False, timeout: float = PAGE_WAIT_S) -> None:
        """A mouse click on the program list's line of entry ``index`` (Shift held: a range). The
        list is one HTML block the page draws anew on every program change, so a line found
        visible can be replaced before the click lands ("not visible", "detached"): the click is
        made again on the line drawn then, which the first never reached."""
        target = self.page.locator(f'[data-program-list] [data-stmt-index="{index}"]')
        for attempt in range(3):
            target.wait_for(state="visible", timeout=timeout * 1000)
            try:
                target.click(force=True, modifiers=["Shift"] if shift else None, timeout=timeout * 1000)
                return
            except PlaywrightError as exc:
                if attempt == 2 or not ("not visible" in str(exc) or "detached" in str(exc)):
                    raise

    def tab(self, name: str) -> None:
        tab = self.page.get_by_role("tab", name=name)
        if tab.get_attribute("aria-selected") != "true":  # a click on the open tab does nothing
            self.press(tab)

    def click(self, label: str) -> None:
        self.press(self.page.get_by_role("button", name=label, exact=True).first)

    def row(self, label: str) -> Locator:
        """The GUI row whose label reads exactly ``label`` (viser puts label and input in one
        flex row; text inputs are not tied to their label by id)."""
        label_el = self.page.locator("label", has_text=re.compile(rf"^{re.escape(label)}$"))
        return self.page.locator(".mantine-Flex-root", has=label_el).last

    def type_into(self, label: str, text: str) -> None:
        box = self.row(label).locator("input").first
        self.press(box)
        box.press("Control+a")
        box.press("Delete")
        box.type(text)

    def choose(self, label: str, option: str, exact: bool = True) -> None:
        self.press(self.row(label).locator("input").first)
        self.page.get_by_role("option", name=option_name(label, option), exact=exact).first.click()  # it slides open: wait

    def choose_when_shown(self, label: str, option: str) -> None:
        """:meth:`choose` for a dropdown whose open list is never "stable" for Playwright's wait
        (the header's lines change 4 times a second): the option is clicked once it is visible."""
        self.press(self.row(label).locator("input").first)
        item = self.page.get_by_role("option", name=option_name(label, option), exact=True).first
        item.wait_for(state="visible")
        time.sleep(0.2)  # it slides open
        item.click(force=True)

    def set_number(self, label: str, value: float) -> None:
        """Type into a number input (or a slider's number box) and press Enter."""
        box = self.number_box(label)
        self.press(box)
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

    def settle(self) -> None:
        """Wait until the page has drawn twice: the pointer events sent before are handled."""
        self.page.evaluate(TWO_FRAMES_JS)

    def drag(self, x0: float, y0: float, x1: float, y1: float, steps: int = 12) -> None:
        self.page.mouse.move(x0, y0)
        self.settle()  # hovered: the handle under the pointer is known before the press
        self.page.mouse.down()
        self.page.mouse.move(x1, y1, steps=steps)
        self.settle()
        self.page.mouse.up()

    def drag_until(self, grabs: list[tuple[float, float]], pull: tuple[float, float], moved, steps: int = 12):
        """Drag from each grab point (canvas pixels) by ``pull`` until ``moved()`` gives something:
        each drag is made once and its effect awaited (``DRAG_EFFECT_S``); only a drag that moved
        nothing in that time (the press missed the handle) is followed by the next grab point, so
        a slow page never gets the same drag twice. Returns what ``moved()`` gave."""
        for x, y in grabs:
            self.drag(x, y, x + pull[0], y + pull[1], steps=steps)
            try:
                return wait_for(moved, timeout=DRAG_EFFECT_S, interval=0.05, what="the drag's effect")
            except AssertionError:
                continue
        raise AssertionError(f"no grab point moved the arm: {grabs}")

    def pointer_sweep(self, x0: float, y: float, amplitude: float, hz: float, seconds: float,
                      period: float = 2.0, every_move: bool = False) -> list[float]:
        """With the mouse button held, feed the canvas ``hz`` pointer moves a second for
        ``seconds``, sweeping ``amplitude`` px either side of ``x0`` (POINTER_SWEEP_JS); returns
        the dispatch times (page clock, ms). With ``every_move`` the sweep makes all
        ``hz * seconds`` moves however long a busy page takes for them (a pacing count), else it
        ends after ``seconds`` (a rate)."""
        return self.page.evaluate(POINTER_SWEEP_JS, [x0, y, amplitude, hz, seconds, period, every_move])

    def drag_gizmo_x(self, pixels: float) -> list[float]:
        """Grab the gizmo's x arrow (the camera looks at the tool from -y, so world x points
        right from the canvas centre) and pull it ``pixels`` to the right; returns the tool
        position (mm) after the first grab that moved it."""
        before = self.session()["arm"]["tool_xyz_mm"]
        cx, cy = self.canvas_center()

        def moved():
            after = self.session()["arm"]["tool_xyz_mm"]
            return after if abs(after[0] - before[0]) > 1.0 else None

        return self.drag_until([(cx + grab, cy) for grab in GIZMO_X_GRABS_PX], (pixels, 0.0), moved)

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

    # -- the peg transfer: submit, follow the sent list, re-sync (all through the page) ------------
    SENT_LINE = re.compile(
        r"^#(?P<number>\d+|\?) (?P<text>.*?): (?P<status>sending|received|running|done|FAILED|skipped|aborted|REJECTED)\b(?P<rest>.*)$",
        re.M,
    )

    def choose_regime(self, value: str) -> None:
        """Override the regime with the status bar's selector (``free``, ``quasi``, ...)."""
        self.choose("Regime", value)

    def insert_statements(self, texts: list[str]) -> None:
        """Type each statement into the program panel's input and insert it before the selected
        trailing empty statement, waiting for each to land (so they keep their order)."""
        for text in texts:
            count = len(self.session()["program"]["entries"])
            self.insert_statement(text)
            wait_for(lambda: len(self.session()["program"]["entries"]) == count + 1,
                     what=f"statement {text!r} inserted (page notice: {self.notice()!r})")

    def notice(self) -> str:
        """The status bar's last notice line as the page shows it ('' if none)."""
        m = re.search(r"^(Refused|Error|Warning|Note):.*$", self.page.inner_text("body"), re.M)
        return m.group(0) if m else ""

    def submit_range(self, first: int, last: int) -> None:
        """On the Submit tab, set the range (numbered from 1 as the page counts) and submit it."""
        self.tab("Submit")

        def shown() -> bool:
            return (self.number_box("Submit from").input_value() == str(first)
                    and self.number_box("Submit to").input_value() == str(last))

        try:  # the page proposes 1..n, all that is in the program: often there is nothing to type
            wait_for(shown, timeout=2.0)
        except AssertionError:
            self.set_number("Submit from", first)
            self.set_number("Submit to", last)
            wait_for(shown, what=f"range {first}-{last} set")
        self.click("Submit range")

    def sent_lines(self) -> list[dict[str, str]]:
        """The sent list as the Submit tab shows it (newest first), returned oldest first: number,
        text and status of each line."""
        return [m.groupdict() for m in self.SENT_LINE.finditer(self.page.inner_text("body"))][::-1]

    def wait_sent_final(self, total: int, timeout: float = 60.0) -> list[dict[str, str]]:
        """Wait until the page lists ``total`` sent statements, none pending, and return the
        lines it shows (the newest ones)."""
        self.tab("Submit")
        self.text_appears(rf"\b{total} sent, 0 pending", timeout=timeout)
        return self.sent_lines()

    def task_actions(self, kind: str) -> list[str]:
        """The Task tab's list of recognised actions: ``virtual``, ``preview`` or ``robot``."""
        return self.page.eval_on_selector_all(
            f'[data-actions="{kind}"] li', "els => els.map(e => e.getAttribute('data-action'))")

    def task_marking(self, kind: str) -> list[str]:
        """The atoms the Task tab shows true in the ``virtual``, ``preview`` or ``robot`` marking."""
        found = self.page.eval_on_selector_all(f'[data-marking="{kind}"]', "els => els.map(e => e.getAttribute('data-atoms'))")
        return [a for a in found[0].split("|") if a] if found else []

    def robot_end_taken(self, timeout: float = PAGE_WAIT_S) -> None:
        """After a contact task (an insertion) that ended done within its declared tolerance: the
        console takes the robot's arm as the program's start by itself; no divergence to re-sync."""
        self.tab("Program")
        self.text_appears(r"Starts from: re-synced from robot", timeout=timeout)
        assert not self.console.api("GET", "/api/divergence").json()["diverged"]
        assert self.page.get_by_role("button", name="Re-sync from robot", exact=True).is_hidden()

    def resync_when_offered(self, timeout: float = 30.0) -> None:
        """Wait for the divergence warning and its re-sync button, then click it."""
        button = self.page.get_by_role("button", name="Re-sync from robot", exact=True)
        button.wait_for(state="visible", timeout=timeout * 1000)
        self.text_appears(r"Divergence:", timeout=5)
        self.press(button)
        button.wait_for(state="hidden", timeout=timeout * 1000)
