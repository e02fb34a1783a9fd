"""``POST /api/task/goal`` (issue 40): a goal of the cell's task space planned from the virtual
marking, its statements inserted into the program as ordinary lines."""

from __future__ import annotations

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
