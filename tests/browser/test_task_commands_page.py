"""Task-level commands from the page (issue 40), in headless Chromium with mouse and keyboard:
on the Task tab the operator clicks the action button ``grasp(PEG)``, types the goal
``PEGINHOLE(PEG,HOLE2), HANDEEMPTY`` into the goal box and clicks Plan goal; the program then
holds the transfer, each line marked with its action, and the Task tab's net shows the planned
path, its transitions numbered in order. In the quasi-operation regime, "Preview and
submit" previews it and sends it over the 200 ms link to the telerobot on contact physics, and the
robot's marking reaches the goal: the peg in HOLE2, the hand empty. The session is read through
GET requests only, to check what the page did.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from console_page import ConsolePage, wait_for
from support import RunningConsole, screenshot_if_failed, start_console, stop_process

pytestmark = pytest.mark.browser

TRANSFER = ["grasp(PEG)", "part(PEG,HOLE1)", "mate(PEG,HOLE2)", "release(PEG)"]


@pytest.fixture(scope="module")
def task_console(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("task_commands_page"), "--delay-ms", "200", "--no-record")
    yield running
    stop_process(running.proc)


@pytest.fixture
def ui(task_console: RunningConsole, chromium, request) -> Iterator[ConsolePage]:
    context = chromium.new_context(viewport={"width": 1400, "height": 900})
    page = ConsolePage(context.new_page(), task_console, quick_clicks=True)
    page.open()
    yield page
    screenshot_if_failed(request, page.page)
    context.close()


def _actions(ui: ConsolePage) -> list[str | None]:
    """The action each program line serves, as the program's view says."""
    return [e.get("action") for e in ui.session()["program"]["entries"] if e["kind"] != "EMPTY"]


def test_an_action_button_and_a_goal_plan_the_transfer_and_the_robot_reaches_the_goal(ui: ConsolePage) -> None:
    ui.text_appears(r"Link: connected", timeout=30)
    ui.text_appears(r"robot idle", timeout=30)
    ui.choose_when_shown("Regime", "quasi")
    ui.tab("Task")
    ui.click("grasp(PEG)")  # the one action the loaded cell enables
    wait_for(lambda: set(_actions(ui)) == {"grasp(PEG)"}, what=f"the grasp's lines (notice {ui.notice()!r})")
    # the buttons follow the program's end: holding the peg, part(PEG,HOLE1) is offered, grasp no more
    ui.page.get_by_role("button", name="part(PEG,HOLE1)", exact=True).wait_for(state="visible", timeout=15_000)
    assert ui.page.get_by_role("button", name="grasp(PEG)", exact=True).count() == 0
    ui.type_into("Goal", "PEGINHOLE(PEG,HOLE2), HANDEEMPTY")
    ui.click("Plan goal")
    wait_for(lambda: list(dict.fromkeys(_actions(ui))) == TRANSFER, what=f"the goal's plan (notice {ui.notice()!r})")
    lines = len(_actions(ui))
    # the net picture shows the planned path: the transitions of the program's actions, numbered in order
    planned = ui.page.locator("[data-task-net] svg g.transition[data-planned]")
    wait_for(lambda: planned.count() == len(TRANSFER), what="the planned path drawn on the net")
    steps = ui.page.eval_on_selector_all(
        "[data-task-net] svg g.transition[data-planned]",
        "els => els.map(e => [Number(e.dataset.planned), e.querySelector('text.label').textContent])")
    assert [action for _, action in sorted(steps)] == TRANSFER

    ui.tab("Preview")
    ui.choose_when_shown("Preview speed", "10x")
    wait_for(lambda: ui.session()["preview"]["speed"] == 10.0, what="10x")
    ui.tab("Submit")
    ui.click("Preview and submit")
    wait_for(lambda: len(ui.session()["sent"]["items"]) >= lines, timeout=60,
             what=f"previewed and sent (notice {ui.notice()!r})")
    sent = ui.session()["sent"]["items"]
    wait_for(lambda: all(s["status"] == "done" for s in ui.session()["sent"]["items"]), timeout=120,
             what=f"every statement done on the robot ({[s['status'] for s in ui.session()['sent']['items']]})")
    # the robot's reports reach the task monitor after the statuses: wait for the last action's
    task = wait_for(lambda: len((t := ui.console.api("GET", "/api/task").json())["robot_actions"]) >= len(TRANSFER) and t,
                    timeout=30, what="the robot's actions on the Task tab")
    assert "PEGINHOLE(PEG,HOLE2)" in task["robot_marking"] and "HANDEEMPTY" in task["robot_marking"], task["robot_marking"]
    assert [a["action"] for a in task["robot_actions"]] == TRANSFER
    assert len(sent) >= lines and not task["deviations"], task["deviations"]
