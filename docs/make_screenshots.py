"""Screenshots of each shipped cell at the console's default camera, for the README's "The view".

    .venv/bin/python docs/make_screenshots.py            # peg, rover terrain, empty PUMA
    .venv/bin/python docs/make_screenshots.py --out /tmp  # elsewhere

Starts ``teleprog up --no-robot --no-record --cell CELL`` for each cell, opens its page in Debian's
headless Chromium (Playwright, the browser tests' launch arguments) at 1400 x 900, waits until the
page has drawn the cell (two pictures of the 3D view in a row alike), and saves
``docs/cell-<name>.png``. The camera is the one a new page gets: nothing here moves it.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from support import CHROMIUM_ARGS, free_port, stop_process, wait_http  # noqa: E402

CELLS = ("peg_in_hole", "rover_terrain", "puma562_empty")
VIEWPORT = {"width": 1400, "height": 900}


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
    parser.add_argument("--out", type=Path, default=ROOT / "docs", help="folder for cell-<name>.png (default docs/)")
    parser.add_argument("--cell", action="append", choices=CELLS, help="only this cell (repeatable)")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    args.out.mkdir(parents=True, exist_ok=True)
    executable = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=executable, headless=True, args=CHROMIUM_ARGS)
        try:
            with tempfile.TemporaryDirectory() as logs:
                for cell in args.cell or CELLS:
                    print(_shoot(browser, cell, args.out, Path(logs)), flush=True)
        finally:
            browser.close()


if __name__ == "__main__":
    main()
