"""The whole peg transfer of thesis §4.6 done from the page in headless Chromium, with mouse and
keyboard only: the operator picks the free-motion regime, types each statement of a piece into the
program panel, submits the piece from the Submit tab, watches every sent statement reach "done" in
the sent list, re-syncs the virtual arm when the page offers it after the insertion, and ends with
the peg standing in HOLE2 and the gripper empty.

The pieces are those of the API test (``tests/e2e/test_console_session.py``), typed line by line
and sent piece by piece (the shipped file in one piece is ``test_peg_transfer_file_page``). The test has its own console
(``teleprog up --delay-ms 200``) so the other browser modules' programs and robot state do not
interfere; the session's state is read through GET requests only, to check what the page showed.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from console_page import ConsolePage, wait_for
from shared.cells.loader import DEFAULT_CELL, load_cell
from support import RunningConsole, screenshot_if_failed, start_console, stop_process
from e2e.test_console_session import PIECES  # the pieces of the API test, word for word

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def transfer_console(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("peg_page"), "--delay-ms", "200")
    yield running
    stop_process(running.proc)


@pytest.fixture
def ui(transfer_console: RunningConsole, chromium, request) -> Iterator[ConsolePage]:
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    page = ConsolePage(context.new_page(), transfer_console, quick_clicks=True)
    page.open()
    yield page
    screenshot_if_failed(request, page.page)
    context.close()


def send_piece(ui: ConsolePage, texts: list[str], sent_before: int) -> int:
    """Type the piece's statements, submit them all, and wait until the page shows each of them
    done; returns the number of statements sent so far."""
    ui.insert_statements(texts)
    ui.text_appears(rf"{len(texts)}: {texts[-1].split()[0]}")  # the program panel lists the last one
    ui.submit_range(1, len(texts))
    total = sent_before + len(texts)
    wait_for(lambda: len(ui.session()["program"]["entries"]) == 1,
             what=f"the piece left the program (page notice: {ui.notice()!r})")
    lines = ui.wait_sent_final(total)
    mine = lines[-len(texts):]
    # the page's last lines are this piece, in order, each numbered by the robot and done
    assert [line["text"].split()[0] for line in mine] == [t.split()[0] for t in texts], mine
    assert all(line["status"] == "done" for line in mine), mine
    numbers = [int(line["number"]) for line in mine]
    assert numbers == list(range(numbers[0], numbers[0] + len(texts))), mine
    return total


def test_peg_transfer_from_the_page(ui: ConsolePage) -> None:
    ui.text_appears(r"Link: connected", timeout=30)
    ui.text_appears(r"robot idle", timeout=30)
    ui.choose_regime("free")
    ui.text_appears(r"Regime: ONLINE \(free zone\) \(operator override\)")
    assert ui.session()["regime"]["regime"] == "free"

    sent = send_piece(ui, PIECES[0], 0)  # above the peg, down to contact, grasp
    ui.tab("Drive")
    ui.text_appears(r"holding peg")  # the virtual gripper holds it as predicted
    wait_for(lambda: ui.console.api("GET", "/api/remote").json()["held"] == "peg", what="the robot holding the peg")
    sent = send_piece(ui, PIECES[1], sent)  # extract it from HOLE1
    sent = send_piece(ui, PIECES[2], sent)  # carry it over HOLE2 and insert it in force mode

    # the insertion ends where contact decides: within insert_peg's declared tolerance the console
    # takes the robot's end as the program's start by itself (issue 37: success looks like success)
    ui.robot_end_taken()
    remote = ui.console.api("GET", "/api/remote").json()
    arm = ui.session()["arm"]
    # the virtual arm stands where the robot does (the physical arm settles by a few 1e-5 rad after)
    np.testing.assert_allclose(arm["q"], remote["q"], atol=2e-4)

    send_piece(ui, PIECES[3], sent)  # position mode, let go
    remote = wait_for(lambda: (r := ui.console.api("GET", "/api/remote").json())["state"] == "idle" and r,
                      what="the robot at rest")
    assert remote["held"] is None
    peg_now = np.asarray(remote["object_poses"]["peg"])
    hole2 = load_cell(DEFAULT_CELL).features["HOLE2"].world_T_feature
    np.testing.assert_allclose(peg_now[:2, 3], hole2[:2, 3], atol=0.003)  # the peg stands in HOLE2
