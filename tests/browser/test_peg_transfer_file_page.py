"""The "Done when" of issue 16: the whole peg transfer of thesis §4.6 from the page, with the
shipped ``assets/programs/peg_transfer.tp`` loaded in one piece through the Program tab's upload
button, previewed to its end on the Preview tab in the quasi-operation (offline) regime, and
submitted with the Submit tab's button, over a real telerobot on contact physics and the thesis's
3 s link (``teleprog up --delay-ms 3000``). It ends with every line of the file done on the robot,
exactly those lines sent, and the physical peg reported standing in HOLE2 with the gripper empty.

The Task tab (issue 18) follows it: the preview's steps show the task actions the range makes one
after another, and while the robot runs the file its reports add grasp, part, mate and release
to the robot's list one by one, the robot's marking moving from HOLE1 to HOLE2.

The same walk is issue 37's "Done when" from the page (success that looks like success): after
the last statement no divergence warning shows at any moment (the insertion's end is the robot's
to report, within the task's declared tolerance, and the console takes it), the virtual arm
stands within 1 mm of the robot's reported tool, and the Task tab's two markings are equal (the
peg in HOLE2, the hand empty) with no deviation. (One walk, one console: it was two tests on two
consoles, each sending the same file over the same 3 s link.)

Before issue 16 the upload was refused ("statement 6 follows the task call at statement 5"): the
editor let nothing follow any task call while ``teleprog check`` accepted the file. Both now read
one rule (``shared.language.task_rule``). The session's state is read through GET requests only.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from console_page import ConsolePage, wait_for
from support import RunningConsole, screenshot_if_failed, start_console, stop_process

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.formatter import format_statement
from shared.language.parser import parse_file
from shared.paths import ASSETS_DIR

pytestmark = pytest.mark.browser

PROGRAM = ASSETS_DIR / "programs" / "peg_transfer.tp"


@pytest.fixture(scope="module")
def file_console(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("peg_file_page"), "--delay-ms", "3000")  # the thesis's link
    yield running
    stop_process(running.proc)


@pytest.fixture
def ui(file_console: RunningConsole, chromium, request) -> Iterator[ConsolePage]:
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    page = ConsolePage(context.new_page(), file_console, quick_clicks=True)
    page.open()
    yield page
    screenshot_if_failed(request, page.page)
    context.close()


def upload_program(ui: ConsolePage, path) -> None:
    """The Program tab's "Load program file" button takes the file (its file input, as a file
    chooser would fill it)."""
    ui.tab("Program")
    button = ui.page.get_by_role("button", name="Load program file")
    button.wait_for(state="visible")
    ui.page.locator("input[type=file]").first.set_input_files(str(path))


TASK_ACTIONS = ["grasp(PEG)", "part(PEG,HOLE1)", "mate(PEG,HOLE2)", "release(PEG)"]
AFTER = ["HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE2)", "HOLEEMPTY(HOLE1)"]


def distinct(seen: list[list[str]], now: list[str]) -> None:
    if not seen or seen[-1] != now:
        seen.append(now)


def preview_to_the_end(ui: ConsolePage, last: int, task_seen: list[list[str]] | None = None) -> None:
    """Start the preview of statements 1..last and step through it to its end (the Step button
    jumps to the end of the statement playing), then End it. ``task_seen`` collects the Task
    tab's preview actions after each step, as they change."""
    ui.tab("Preview")
    wait_for(lambda: ui.number_box("To statement").input_value() == str(last), what=f"the preview range 1-{last}")
    ui.click("Start preview")
    wait_for(lambda: ui.session()["preview"]["active"], what=f"the preview running (page notice: {ui.notice()!r})")
    for _ in range(3 * last):
        if task_seen is not None:
            distinct(task_seen, ui.task_actions("preview"))
        if ui.session()["program"]["confirmed"] == [0, last]:
            break
        ui.click("Step")
    wait_for(lambda: ui.session()["program"]["confirmed"] == [0, last], what="the range previewed to its end")
    if task_seen is not None:  # at the end the page shows every action of the range
        wait_for(lambda: (distinct(task_seen, ui.task_actions("preview")), task_seen[-1] == TASK_ACTIONS)[1],
                 what="the preview's task actions complete on the Task tab")
    ui.text_appears(r"No warnings\.")
    ui.click("End")
    wait_for(lambda: not ui.session()["preview"]["active"], what="the preview ended")


def test_the_shipped_peg_transfer_from_the_page_in_one_piece(ui: ConsolePage) -> None:
    expected = [format_statement(s) for s in parse_file(PROGRAM).statements]
    ui.text_appears(r"Link: connected", timeout=30)
    ui.text_appears(r"robot idle", timeout=30)
    ui.choose_regime("quasi")
    wait_for(lambda: ui.session()["regime"]["regime"] == "quasi", what="the quasi-operation regime")

    upload_program(ui, PROGRAM)
    wait_for(lambda: len(ui.session()["program"]["entries"]) == len(expected) + 1,
             what=f"the file loaded (page notice: {ui.notice()!r})")
    ui.text_appears(rf"{len(expected)}: MODE POSITION", timeout=30)  # the program list shows the file's last line
    assert [e["text"] for e in ui.session()["program"]["entries"][:-1]] == expected

    ui.tab("Task")  # viser mounts a tab's content when it is first opened; it stays mounted after
    assert ui.task_marking("robot") == ["HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE1)", "HOLEEMPTY(HOLE2)"]
    preview_seen: list[list[str]] = []
    preview_to_the_end(ui, len(expected), preview_seen)
    # the preview's steps showed the actions in order, more than one step apart, ending with all four
    assert all(s == TASK_ACTIONS[:len(s)] for s in preview_seen), preview_seen
    assert preview_seen[0] == [] and preview_seen[-1] == TASK_ACTIONS and len(preview_seen) >= 3, preview_seen
    ui.submit_range(1, len(expected))
    wait_for(lambda: len(ui.session()["program"]["entries"]) == 1,
             what=f"the program left for the robot (page notice: {ui.notice()!r})")
    robot_seen: list[list[str]] = []
    wait_for(lambda: (distinct(robot_seen, ui.task_actions("robot")), robot_seen[-1] == TASK_ACTIONS)[1],
             timeout=90, interval=0.1, what=f"the robot's four task actions on the Task tab (seen {robot_seen})")
    # in order, as the reports come: each list the page showed is the start of the next, and the
    # page showed at least one in between (grasp and part, mate and release are each a few tenths
    # of a second apart, which a loaded machine's page may show as one step)
    assert all(s == TASK_ACTIONS[:len(s)] for s in robot_seen), robot_seen
    assert robot_seen[0] == [] and len(robot_seen) >= 3, robot_seen
    assert "PEGINHOLE(PEG,HOLE2)" in ui.task_marking("robot") and "HOLEEMPTY(HOLE1)" in ui.task_marking("robot")
    assert ui.page.locator("[data-deviation]").count() == 0
    lines = ui.wait_sent_final(len(expected), timeout=90)
    # the page lists exactly the file's statements, each numbered by the robot in order and done
    assert [line["text"] for line in lines[-len(expected):]] == expected, lines
    assert all(line["status"] == "done" for line in lines[-len(expected):]), lines
    sent = ui.console.api("GET", "/api/sent").json()["items"]
    assert [s["text"] for s in sent] == expected  # nothing went that was not a line of the file

    remote = wait_for(lambda: (r := ui.console.api("GET", "/api/remote").json())["state"] == "idle" and r,
                      what="the robot at rest")
    assert remote["held"] is None
    peg_now = np.asarray(remote["object_poses"]["peg"])
    hole2 = load_cell(DEFAULT_CELL).features["HOLE2"].world_T_feature
    np.testing.assert_allclose(peg_now[:2, 3], hole2[:2, 3], atol=0.003)  # the peg stands in HOLE2
    foot_z = peg_now[2, 3] - 0.040  # the 80 mm peg's foot, as the physics left it
    assert foot_z < hole2[2, 3] - 0.029, f"the peg's foot is {1e3 * (hole2[2, 3] - foot_z):.1f} mm into the 30 mm hole"

    # one truth: the console took the insertion's end as the program's start, so once the robot
    # rests the virtual arm stands within 1 mm of it and no divergence is told
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
