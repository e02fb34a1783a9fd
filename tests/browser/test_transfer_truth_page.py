"""Issue 37's "Done when" from the page: the shipped peg transfer over the thesis's 3 s link
(``teleprog up --delay-ms 3000``, the telerobot on contact physics), loaded with the Program tab's
button, previewed to its end and submitted from the Submit tab, ends

* with every statement done and no divergence warning on the page at any moment after it (the
  insertion's end is the robot's to report, within the task's declared tolerance, and the console
  takes it);
* with the virtual arm within 1 mm of the robot's reported tool;
* with the Task tab's two markings equal (the peg in HOLE2, the hand empty) and no deviation.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from console_page import ConsolePage, wait_for
from support import RunningConsole, screenshot_if_failed, start_console, stop_process
from test_peg_transfer_file_page import PROGRAM, preview_to_the_end, upload_program

from shared.language.parser import parse_file

pytestmark = pytest.mark.browser

AFTER = ["HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE2)", "HOLEEMPTY(HOLE1)"]


@pytest.fixture(scope="module")
def slow_link_console(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("transfer_truth_page"), "--delay-ms", "3000", "--no-record")
    yield running
    stop_process(running.proc)


@pytest.fixture
def ui(slow_link_console: RunningConsole, chromium, request) -> Iterator[ConsolePage]:
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    page = ConsolePage(context.new_page(), slow_link_console, quick_clicks=True)
    page.open()
    yield page
    screenshot_if_failed(request, page.page)
    context.close()


def test_a_successful_transfer_from_the_page_ends_in_one_truth(ui: ConsolePage) -> None:
    total = len(parse_file(PROGRAM).statements)
    ui.text_appears(r"Link: connected", timeout=30)
    ui.text_appears(r"robot idle", timeout=30)
    ui.choose_regime("quasi")
    wait_for(lambda: ui.session()["regime"]["regime"] == "quasi", what="the quasi-operation regime")
    upload_program(ui, PROGRAM)
    wait_for(lambda: len(ui.session()["program"]["entries"]) == total + 1, what=f"the file loaded ({ui.notice()!r})")
    ui.tab("Task")  # mounted once opened
    preview_to_the_end(ui, total)
    ui.submit_range(1, total)
    lines = ui.wait_sent_final(total, timeout=120)
    assert all(line["status"] == "done" for line in lines[-total:]), lines

    api = ui.console.api

    def at_rest_in_step():
        remote, arm, divergence = (api("GET", p).json() for p in ("/api/remote", "/api/arm", "/api/divergence"))
        if remote["state"] != "idle" or not divergence["checked"]:
            return None
        gap = np.linalg.norm(np.asarray(arm["world_T_tcp"])[:3, 3] - np.asarray(remote["world_T_tcp"])[:3, 3])
        return divergence if gap < 1e-3 else None

    divergence = wait_for(at_rest_in_step, timeout=30, what="the virtual arm within 1 mm of the robot at rest")
    assert not divergence["diverged"], divergence
    assert not ui.page.get_by_text("Divergence:").is_visible()
    ui.tab("Task")
    wait_for(lambda: ui.task_marking("robot") == AFTER, timeout=30, what="the robot's marking with the peg in HOLE2")
    assert ui.task_marking("virtual") == ui.task_marking("robot") == AFTER
    assert ui.page.locator("[data-deviation]").count() == 0
    assert api("GET", "/api/task").json()["deviations"] == []
