"""Shared fixtures: the console as a real process, headless Chromium."""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from pathlib import Path

import pytest

# the robot's credential (shared.wire.credential) for every robot, console and client the tests
# start; tests of the robot's door start theirs without it or with another
os.environ.setdefault("TELEPROG_ROBOT_CREDENTIAL", "tests-" + secrets.token_urlsafe(16))

from support import CHROMIUM_ARGS, RunningConsole, screenshot_if_failed, start_console, stop_process


@pytest.fixture(scope="session", autouse=True)
def recordings_folder(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """Every console a test starts (in this process or as a child) records into a folder of the
    session's pytest temporary directory, never into the project's recordings/ and never into a
    folder left behind in /tmp: pytest removes it with its old temporary directories. A folder
    set from outside (``TELEPROG_RECORD_DIR``) is kept."""
    outside = os.environ.get("TELEPROG_RECORD_DIR")
    if outside:
        yield Path(outside)
        return
    folder = tmp_path_factory.mktemp("recordings", numbered=False)
    os.environ["TELEPROG_RECORD_DIR"] = str(folder)
    try:
        yield folder
    finally:
        os.environ.pop("TELEPROG_RECORD_DIR", None)


@pytest.fixture
def console(tmp_path: Path) -> Iterator[RunningConsole]:
    running = start_console(tmp_path)
    yield running
    stop_process(running.proc)


@pytest.fixture(scope="module")
def linked_console(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    """The console with its own telerobot and a delayed link (200 ms each way), as
    ``teleprog up`` starts them; one per test module (starting the three takes seconds)."""
    running = start_console(tmp_path_factory.mktemp("linked"), "--delay-ms", "200")
    yield running
    stop_process(running.proc)


@pytest.fixture(scope="module")
def chromium():
    """Debian's chromium through Playwright's sync API, one per module: that API runs an event
    loop in the main thread while it is open, and a test that calls ``asyncio.run`` cannot run
    inside it, so it closes with the module and tests may run in any order of modules."""
    from playwright.sync_api import sync_playwright

    executable = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    if not Path(executable).exists():
        pytest.fail(f"Debian's chromium is needed for browser tests ({executable} not found); run scripts/test")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=executable, headless=True, args=CHROMIUM_ARGS)
        yield browser
        browser.close()


@pytest.fixture
def page(chromium, request):
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    page = context.new_page()
    yield page
    screenshot_if_failed(request, page)
    context.close()


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    setattr(item, "rep_" + rep.when, rep)
