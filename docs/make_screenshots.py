"""Screenshots for the README: each shipped cell at its default camera, and a first session.

The cells are shown in the README and in "The view" of docs/console.md; the session, with a robot
over a delayed link, in the README's "First session".

    .venv/bin/python docs/make_screenshots.py                  # all of them
    .venv/bin/python docs/make_screenshots.py --cell rover_terrain
    .venv/bin/python docs/make_screenshots.py --session        # only the first session's five
    .venv/bin/python docs/make_screenshots.py --out /tmp        # elsewhere

Cells: starts ``teleprog up --no-robot --no-record --cell CELL`` for each cell, opens its page in
Debian's headless Chromium (Playwright, the browser tests' launch arguments) at 1400 x 900, waits
until the page has drawn the cell (two pictures of the 3D view in a row alike), and saves
``docs/cell-<name>.png``. The camera is the one a new page gets: nothing here moves it.

Session: starts ``teleprog up --delay-ms 500 --no-record`` (telerobot, link and console on the
peg-in-hole cell), opens the page at 1400 x 1000 with its default camera, and drives the session
the way the README's "First session" tells it: two strokes through the API an operator's drags
make (``/api/jog/tool`` along work y to above the peg, ``/api/jog/joint`` on J6, each let go with
``/api/jog/release``: one statement each), the first statement slowed with ``/api/program/modify``;
then on the page itself: Start preview and Play (Preview tab), End, Submit range (Submit tab),
STOP while the first statement runs, Resume. Each picture is taken once the page shows the step's
own words (checked here, so a renamed label fails the script): ``docs/session-drive.png``,
``session-program.png``, ``session-preview.png``, ``session-submit.png``, ``session-stop.png``.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from support import CHROMIUM_ARGS, free_port, stop_process, wait_for, wait_http  # noqa: E402

CELLS = ("peg_in_hole", "rover_terrain", "puma562_empty")
VIEWPORT = {"width": 1400, "height": 900}
SESSION_VIEWPORT = {"width": 1400, "height": 1000}  # the panel's lists need the height


def _shoot(browser, cell: str, out: Path, log_dir: Path) -> Path:
    port = free_port()
    log = (log_dir / f"screenshot-{cell}.log").open("w")
    proc = subprocess.Popen(
        [sys.executable, "-m", "server.cli", "up", "--no-robot", "--no-record", "--port", str(port),
         "--cell", str(ROOT / "assets" / "cells" / f"{cell}.toml")],
        stdout=log, stderr=subprocess.STDOUT, cwd=ROOT, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        url = f"http://127.0.0.1:{port}"
        wait_http(f"{url}/api/health", proc, timeout=240.0)
        assert httpx.get(f"{url}/api/health").json()["cell"] == cell
        context = browser.new_context(viewport=VIEWPORT)
        page = context.new_page()
        page.goto(url + "/")
        page.wait_for_selector("canvas", timeout=60_000)
        page.get_by_role("button", name="STOP").wait_for(timeout=60_000)
        page.get_by_role("button", name="Front", exact=True).wait_for(timeout=60_000)
        _close_notices(page)
        _wait_drawn(page)
        path = out / f"cell-{cell}.png"
        page.screenshot(path=str(path))
        context.close()
        return path
    finally:
        stop_process(proc)
        log.close()


# -- a first session, with a robot over a 0.5 s link ----------------------------------------------
APPROACH = "DRAW TO (0, -80, 140) mm IN WORK"  # what the first stroke writes: above the peg
SLOW_APPROACH = APPROACH + " WITH SPEED 5 mm/s"  # 16 s: time to see the ghost follow, and to STOP it


def _session(browser, out: Path, log_dir: Path) -> list[Path]:
    port = free_port()
    log = (log_dir / "screenshot-session.log").open("w")
    proc = subprocess.Popen(
        [sys.executable, "-m", "server.cli", "up", "--delay-ms", "500", "--no-record", "--port", str(port)],
        stdout=log, stderr=subprocess.STDOUT, cwd=ROOT, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    shots: list[Path] = []
    try:
        url = f"http://127.0.0.1:{port}"
        wait_http(f"{url}/api/health", proc, timeout=240.0)
        api = httpx.Client(base_url=url, timeout=60.0)
        wait_for(lambda: api.get("/api/link").json()["connected"], 120.0, what="the link")
        context = browser.new_context(viewport=SESSION_VIEWPORT)
        page = context.new_page()
        page.goto(url + "/")
        page.wait_for_selector("canvas", timeout=120_000)
        page.get_by_role("button", name="STOP").wait_for(timeout=120_000)
        page.get_by_role("button", name="Front", exact=True).wait_for(timeout=120_000)
        _close_notices(page)
        _wait_drawn(page, 120.0)

        def shoot(name: str) -> None:
            path = out / f"session-{name}.png"
            page.screenshot(path=str(path))
            shots.append(path)
            print(path, flush=True)

        def shows(pattern: str, timeout: float = 60.0) -> None:
            regex = re.compile(pattern)
            wait_for(lambda: regex.search(page.inner_text("body")), timeout, 0.2, f"/{pattern}/ on the page")

        def click(name: str) -> None:
            button = page.get_by_role("button", name=name, exact=True).first
            wait_for(button.is_enabled, 60.0, 0.1, f"{name} enabled")
            button.click()

        def tab(name: str) -> None:
            page.get_by_role("tab", name=name).click()

        # 1. drive: the regime the zone sets near the peg is OFFLINE; a stroke of the tool along
        # work y to above the peg, let go; a turn of J6, let go: two statements
        shows(r"OFFLINE \(quasi-operation\)")
        for _ in range(8):
            api.post("/api/jog/tool", json={"frame": "work", "constraint": "y", "motion": "translate",
                                            "displacement": [0, -10, 0]}).raise_for_status()
        api.post("/api/jog/release").raise_for_status()
        for _ in range(5):
            api.post("/api/jog/joint", json={"joint": 6, "delta_deg": 3}).raise_for_status()
        program = api.post("/api/jog/release").json()
        texts = [e["text"] for e in program["entries"]]
        assert texts[0] == APPROACH and texts[1].startswith("DRIVE J6 TO") and len(texts) == 3, texts
        tab("Drive")
        shows(r"Tool \(world\): x 550\.0 mm, y -80\.0 mm")
        shows(r"Nearest: peg at")
        _wait_drawn(page, 120.0)
        shoot("drive")

        # 2. the program: the generated statements; the approach slowed (an edit on its line)
        api.post("/api/program/select", json={"index": 0}).raise_for_status()
        api.post("/api/program/modify", json={"text": SLOW_APPROACH}).raise_for_status()
        api.post("/api/program/select", json={"index": 2}).raise_for_status()
        tab("Program")
        shows(re.escape("1: " + SLOW_APPROACH))
        shows(r"Starts from: .*planned")
        shoot("program")

        # 3. preview on the page: Start preview, Play; the picture mid-play
        tab("Preview")
        click("Start preview")
        shows(r"Statements 1-2: t = ")
        click("Play")
        shows(r"\(playing\)")
        shows(r"Playing statement 1")
        wait_for(lambda: api.get("/api/preview").json()["t"] > 6.0, 60.0, 0.2, "the preview half-way")
        shows(r"No warnings\.")
        shoot("preview")
        wait_for(lambda: not api.get("/api/preview").json()["playing"], 120.0, 0.2, "the preview's end")
        click("End")
        wait_for(lambda: not api.get("/api/preview").json()["active"], 60.0, 0.2, "the preview ended")
        assert api.get("/api/program").json()["confirmed"] == [0, 2]

        # 4. submit on the page; the picture while the approach runs (the ghost on its way)
        tab("Submit")
        shows(r"Submit range")
        click("Submit range")
        wait_for(lambda: any(s["status"] == "running" for s in api.get("/api/sent").json()["items"]),
                 60.0, 0.1, "the approach running")
        shows(r"2 sent, \d pending")
        shows(r"#\d+ DRAW TO .*: running")  # the page draws the backticks as code
        time.sleep(2.0)  # the ghost some way along
        shoot("submit")

        # 5. STOP on the page while the approach runs; the robot's confirmation; then Resume
        click("STOP")
        shows(r"Robot confirmed STOP")
        shows(r"Robot STOPPED: holding; resume, skip or abort")
        wait_for(page.get_by_role("button", name="Resume", exact=True).is_enabled, 60.0, 0.1, "Resume on")
        time.sleep(1.0)
        shoot("stop")
        click("Resume")
        wait_for(lambda: (s := api.get("/api/sent").json())["pending"] == 0 and s, 120.0, 0.2, "every statement final")
        finals = [s["status"] for s in api.get("/api/sent").json()["items"]]
        assert finals == ["done", "done"], finals
        context.close()
        return shots
    finally:
        stop_process(proc)
        log.close()


def _wait_drawn(page, timeout: float = 60.0) -> None:
    """Until two pictures of the 3D view, half a second apart, are alike (the meshes have arrived
    and software WebGL has drawn them)."""
    canvas = page.locator("canvas").first
    last, deadline = b"", time.monotonic() + timeout
    while time.monotonic() < deadline:
        shot = canvas.screenshot()
        if shot == last:
            return
        last = shot
        time.sleep(0.5)
    raise TimeoutError("the 3D view kept changing")


def _close_notices(page) -> None:
    """The browser's own notice ("software WebGL rendering") covers the view's top left: close it
    (it slides in, so a click may miss; a few tries)."""
    notices = page.locator(".mantine-Notification-root")
    try:
        notices.first.wait_for(timeout=10_000)
    except Exception:  # noqa: BLE001 - no notice: nothing to close
        return
    for _ in range(5):
        buttons = page.locator(".mantine-Notification-closeButton")
        for i in range(buttons.count()):
            try:
                buttons.nth(i).click(timeout=1_000, force=True)
            except Exception:  # noqa: BLE001 - closed by itself
                pass
        try:
            notices.first.wait_for(state="hidden", timeout=3_000)
            return
        except Exception:  # noqa: BLE001 - still there: try again
            continue
    raise TimeoutError("the browser's notice would not close")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs", help="folder for the pictures (default docs/)")
    parser.add_argument("--cell", action="append", choices=CELLS, help="only this cell (repeatable)")
    parser.add_argument("--session", action="store_true", help="the first session's pictures (session-*.png)")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    cells = args.cell or ([] if args.session else list(CELLS))
    session = args.session or not args.cell
    args.out.mkdir(parents=True, exist_ok=True)
    executable = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=executable, headless=True, args=CHROMIUM_ARGS)
        try:
            with tempfile.TemporaryDirectory() as logs:
                for cell in cells:
                    print(_shoot(browser, cell, args.out, Path(logs)), flush=True)
                if session:
                    try:
                        _session(browser, args.out, Path(logs))
                    except BaseException:
                        print((Path(logs) / "screenshot-session.log").read_text()[-4000:], file=sys.stderr)
                        raise
        finally:
            browser.close()


if __name__ == "__main__":
    main()
