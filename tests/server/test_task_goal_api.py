"""``POST /api/task/goal`` (issue 40): a goal of the cell's task space planned from the virtual
marking, its statements inserted into the program as ordinary lines."""

from __future__ import annotations

import numpy as np
from fastapi.testclient import TestClient

from server.app import create_app
from server.settings import ConsoleSettings

TRANSFER = ["grasp(PEG)", "part(PEG,HOLE1)", "mate(PEG,HOLE2)", "release(PEG)"]


def test_a_goal_inserts_the_plan_and_an_unreachable_one_is_refused() -> None:
    with TestClient(create_app(ConsoleSettings(no_robot=True), build_page=False)) as client:
        r = client.post("/api/task/goal", json={"goal": ["PEGINHOLE(PEG,HOLE2)"]})
        assert r.status_code == 200, r.text
        data = r.json()
        assert data["actions"] == TRANSFER
        inserted = [s for row in data["statements"] for s in row["statements"]]
        assert inserted[3] == "TASK grasp(peg)"
        texts = [e["text"] for e in client.get("/api/program").json()["entries"] if e["kind"] != "EMPTY"]
        assert [t for t in texts if t.startswith("TASK")] == [s for s in inserted if s.startswith("TASK")]
        assert len(texts) >= len(inserted)
        bad = client.post("/api/task/goal", json={"goal": ["PEGINHOLE(PEG,HOLE1)", "PEGINHOLE(PEG,HOLE2)"]})
        assert bad.status_code == 400 and "PEGINHOLE(PEG,HOLE2)" in bad.json()["detail"]
        after = [e["text"] for e in client.get("/api/program").json()["entries"] if e["kind"] != "EMPTY"]
        assert after == texts


def _program(client) -> list[dict]:
    return [e for e in client.get("/api/program").json()["entries"] if e["kind"] != "EMPTY"]


def test_a_goals_plan_is_one_edit_and_each_line_names_its_action() -> None:
    with TestClient(create_app(ConsoleSettings(no_robot=True), build_page=False)) as client:
        data = client.post("/api/task/goal", json={"goal": ["PEGINHOLE(PEG,HOLE2)"]}).json()
        lines = _program(client)
        assert [e["action"] for e in lines] == [row["action"] for row in data["statements"] for _ in row["statements"]]
        assert [e["text"] for e in lines] == [s for row in data["statements"] for s in row["statements"]]
        assert client.post("/api/program/undo").status_code == 200
        assert _program(client) == []  # one undo takes the whole plan out
        client.post("/api/program/redo")
        assert [e["action"] for e in _program(client)] == [e["action"] for e in lines]


def test_an_action_the_marking_enables_inserts_its_lines_and_one_it_does_not_is_refused() -> None:
    with TestClient(create_app(ConsoleSettings(no_robot=True), build_page=False)) as client:
        offered = client.get("/api/task/actions").json()
        assert offered["enabled"] == ["grasp(PEG)"]  # the loaded cell: the peg stands in HOLE1, the hand empty
        refused = client.post("/api/task/action", json={"action": "mate(PEG,HOLE2)"})
        assert refused.status_code == 409 and "HOLDING(PEG) does not hold" in refused.json()["detail"]
        unknown = client.post("/api/task/action", json={"action": "polish(PEG)"})
        assert unknown.status_code == 400 and "grasp(PEG)" in unknown.json()["detail"]  # the actions are listed
        r = client.post("/api/task/action", json={"action": " Grasp( peg ) "})
        assert r.status_code == 200, r.text
        assert r.json()["action"] == "grasp(PEG)" and r.json()["statements"][-1] == "TASK grasp(peg)"
        assert [e["action"] for e in _program(client)] == ["grasp(PEG)"] * len(r.json()["statements"])
        # an action's lines are ordinary lines: the operator edits them as any other
        assert client.post("/api/program/select", json={"index": 0}).status_code == 200
        assert client.post("/api/program/delete", json={}).status_code == 200
        assert len(_program(client)) == len(r.json()["statements"]) - 1


def test_task_commands_need_control_before_any_work() -> None:
    with TestClient(create_app(ConsoleSettings(no_robot=True), build_page=False)) as client:
        held = client.post("/api/control/request", headers={"X-Teleprog-Client": "alice"})
        assert held.status_code == 200, held.text
        for path, body in (("/api/task/goal", {"goal": ["PEGINHOLE(PEG,HOLE2)"]}), ("/api/task/action", {"action": "grasp(PEG)"})):
            r = client.post(path, json=body, headers={"X-Teleprog-Client": "bob"})
            assert r.status_code == 409 and "control" in r.json()["detail"], (path, r.status_code, r.text)
        assert _program(client) == []


def test_task_commands_continue_from_where_the_program_leaves_the_cell() -> None:
    """An action button after another, or a goal after both, plans from the end of the program as
    it stands (its play on the virtual cell), not from the virtual cell before it."""
    with TestClient(create_app(ConsoleSettings(no_robot=True), build_page=False)) as client:
        assert client.post("/api/task/action", json={"action": "grasp(PEG)"}).status_code == 200
        offered = client.get("/api/task/actions").json()["enabled"]
        assert "part(PEG,HOLE1)" in offered and "grasp(PEG)" not in offered  # the program holds the peg
        again = client.post("/api/task/action", json={"action": "grasp(PEG)"})
        assert again.status_code == 409 and "HANDEEMPTY" in again.json()["detail"]
        held = client.post("/api/task/goal", json={"goal": ["PEGINHOLE(PEG,HOLE2)"]}).json()
        assert held["actions"] == TRANSFER[1:3]  # the grasp is in the program; the hand keeps what it holds
        assert client.post("/api/program/undo").status_code == 200
        r = client.post("/api/task/goal", json={"goal": ["PEGINHOLE(PEG,HOLE2)", "HANDEEMPTY"]})
        assert r.status_code == 200, r.text
        assert r.json()["actions"] == TRANSFER[1:]
        lines = _program(client)
        assert [e["action"] for e in lines if e["text"].startswith("TASK")] == TRANSFER
        assert client.get("/api/task/actions").json()["enabled"] == ["grasp(PEG)"]  # the peg stands in HOLE2, the hand empty
        # previewed whole, the program is recognised as the transfer
        n = len(lines)
        assert client.post("/api/preview/begin", json={"start": 0, "stop": n}).status_code == 200
        seen = client.post("/api/preview/seek", json={"t": client.get("/api/preview").json()["duration"]})
        assert seen.status_code == 200, seen.text
        client.app.state.console.session.task.settled()  # the range is played on the task panel's thread
        client.post("/api/preview/seek", json={"t": client.get("/api/preview").json()["duration"]})
        task = client.get("/api/task").json()
        assert [a["action"] for a in task["preview_actions"]] == TRANSFER
        assert "PEGINHOLE(PEG,HOLE2)" in task["preview_marking"] and "HANDEEMPTY" in task["preview_marking"]


def test_the_second_task_space_plans_through_the_api_up_to_what_the_robot_must_report() -> None:
    """The two-peg cell: PEGB into HOLE1 needs PEGA moved out first. The first transfer goes in;
    what would move the arm after its insertion waits for the robot's report and is named."""
    from shared.paths import ASSETS_DIR

    settings = ConsoleSettings(no_robot=True, cell=ASSETS_DIR / "cells" / "two_pegs.toml")
    with TestClient(create_app(settings, build_page=False)) as client:
        offered = client.get("/api/task/actions").json()["enabled"]
        assert offered == ["grasp(PEGA)", "grasp(PEGB)"]
        r = client.post("/api/task/goal", json={"goal": ["PEGINHOLE(PEGB,HOLE1)", "HANDEEMPTY"], "keep": False})
        assert r.status_code == 200, r.text
        data = r.json()
        first = ["grasp(PEGA)", "part(PEGA,HOLE1)", "mate(PEGA,HOLE3)", "release(PEGA,HOLE3)"]
        assert data["actions"][:4] == first and [row["action"] for row in data["statements"]] == first
        assert data["deferred"] == ["grasp(PEGB)", "part(PEGB,HOLE2)", "mate(PEGB,HOLE1)", "release(PEGB,HOLE1)"]
        assert list(dict.fromkeys(e["action"] for e in _program(client))) == first
        assert "TASK grasp(peg_a)" in [e["text"] for e in _program(client)]


def test_the_inserted_lines_are_checked_as_a_preview_checks_them() -> None:
    """A plan whose statements the preview's check finds fault with says so, naming the line: the
    virtual peg moved where the approach drives the fingers into the plate."""
    with TestClient(create_app(ConsoleSettings(no_robot=True), build_page=False)) as client:
        clean = client.post("/api/task/goal", json={"goal": ["PEGINHOLE(PEG,HOLE2)", "HANDEEMPTY"]}).json()
        assert clean["warnings"] == []
        client.post("/api/program/undo")
        session = client.app.state.console.session
        # the peg modelled sunk 60 mm into the plate beside HOLE1: the grip descends into the plate
        peg = next(o for o in session.cell.objects if o.name == "peg")
        sunk = np.array(peg.world_T_object, dtype=float)
        sunk[:3, 3] += [0.0, 0.04, -0.06]
        session.arm.objects.placed["peg"] = sunk  # the virtual cell's object world, as a re-located peg would be
        r = client.post("/api/task/action", json={"action": "grasp(PEG)"})
        assert r.status_code == 200, r.text
        warnings = r.json()["warnings"]
        assert warnings and all(w.startswith("statement ") for w in warnings), warnings
        assert any("plate" in w or "table" in w for w in warnings), warnings
