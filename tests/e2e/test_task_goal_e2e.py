"""A goal's plan through the API on real processes (issue 40), on every shipped task space:
``teleprog up --cell CELL`` (telerobot on contact physics, a 200 ms link, the console), a goal
posted to ``/api/task/goal``, its plan previewed without a warning (no collision, every
statement planned), previewed-and-submitted over the link, every statement done on the robot, and
the robot's marking, recognised from what it reports, holding the goal with no task deviation.
"""

from __future__ import annotations

import pytest

from shared.paths import ASSETS_DIR
from support import start_console, stop_process, wait_for

pytestmark = pytest.mark.slow

SHIPPED = sorted(p.stem for p in (ASSETS_DIR / "tasks").glob("*.toml") if (ASSETS_DIR / "cells" / p.name).exists())
GOALS = {  # a goal of each shipped task space: a whole transfer from the cell as loaded
    "peg_in_hole": ["PEGINHOLE(PEG,HOLE2)", "HANDEEMPTY"],
    "two_pegs": ["PEGINHOLE(PEGA,HOLE3)", "HANDEEMPTY"],
}


def test_every_shipped_task_space_has_a_goal_here() -> None:
    assert SHIPPED and set(SHIPPED) == set(GOALS), SHIPPED


@pytest.mark.parametrize("cell", SHIPPED)
def test_a_goals_plan_previews_clean_and_the_robot_reaches_the_goal(cell: str, tmp_path) -> None:
    console = start_console(tmp_path, "--cell", str(ASSETS_DIR / "cells" / f"{cell}.toml"), "--delay-ms", "200",
                            "--no-record")
    api = console.call
    try:
        wait_for(lambda: api("GET", "/api/link")["status"] == "live", 60, 0.1, "a live link")
        wait_for(lambda: api("GET", "/api/remote")["state"] == "idle", 60, 0.1, "the robot idle")
        plan = api("POST", "/api/task/goal", {"goal": GOALS[cell]})
        assert plan["deferred"] == [] and len(plan["actions"]) == 4, plan["actions"]
        n = api("GET", "/api/program")["empty_index"]
        assert n == sum(len(row["statements"]) for row in plan["statements"])
        api("PUT", "/api/regime", {"regime": "quasi"})
        view = api("POST", "/api/preview/begin", {"start": 0, "stop": n})
        assert not view["warnings"], view["warnings"]  # no collision, every statement planned
        api("POST", "/api/preview/end")
        api("POST", "/api/preview/speed", {"speed": "instant"})
        api("POST", "/api/preview/submit", {"start": 0, "stop": n})
        sent = wait_for(lambda: (s := api("GET", "/api/sent"))["pending"] == 0 and len(s["items"]) == n and s,
                        120, 0.1, "every statement final")
        assert [s["status"] for s in sent["items"]] == ["done"] * n, [(s["text"], s["status"], s["reason"]) for s in sent["items"]]
        task = wait_for(lambda: (t := api("GET", "/api/task"))["robot_actions"] and set(GOALS[cell]) <= set(t["robot_marking"]) and t,
                        30, 0.1, f"the robot's marking holding {GOALS[cell]}")
        assert [a["action"] for a in task["robot_actions"]] == plan["actions"]
        assert task["deviations"] == [], [d["message"] for d in task["deviations"]]
    finally:
        stop_process(console.proc)
