"""Task monitoring on the real processes (thesis 3.5, issue 18): ``teleprog up`` with a telerobot
whose peg sticks in its hole on contact physics: world seed 1 puts the plate 2 mm off across the
fingers, closing them presses the peg on its hole's wall through the compliant wrist, and dry
friction (0.6) holds it past the extraction's 40 N.
The grasp is recognised on the robot's side; the extraction fails, and the task net flags the
missing ``part(PEG,HOLE1)`` as a deviation in ``GET /api/task`` and on ``/api/events``."""

from __future__ import annotations

import json
import threading

import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect as connect_ws

from support import start_console, stop_process, wait_for

pytestmark = pytest.mark.slow

APPROACH = ["SPEED 50 %", "MOVES TO (0, -80, 160) mm (180, 0, 0) deg IN WORK",
            "DRAW TO (0, -80, 75) mm IN WORK WITH SPEED 40 mm/s UNTIL CONTACT", "TASK grasp(peg)"]
CLIENT = {"X-Teleprog-Client": "trial"}
STICKY_WORLD = {"SEED": "1", "OBJECT_OFFSET": "0.002", "FRICTION": "0.6"}  # the physics sticks the peg


def test_a_stuck_peg_is_a_task_deviation_with_the_transition_expected(tmp_path, monkeypatch) -> None:
    for name, value in STICKY_WORLD.items():
        monkeypatch.setenv(f"TELEPROG_ROBOT_WORLD__{name}", value)
    console = start_console(tmp_path, "--delay-ms", "200", "--no-record")
    seen: list[dict] = []

    ws = connect_ws(console.url.replace("http", "ws", 1) + "/api/events", max_size=None)

    def listen() -> None:
        try:
            for raw in ws:
                event = json.loads(raw)
                if event.get("type") == "task":
                    seen.append(event)
        except ConnectionClosed:
            pass

    threading.Thread(target=listen, daemon=True).start()
    try:
        api = lambda m, p, b=None: console.call(m, p, b)  # noqa: E731
        wait_for(lambda: api("GET", "/api/link")["status"] == "live", 60, 0.1, "a live link")
        task = api("GET", "/api/task")
        assert task["available"] and task["robot_marking"] == ["HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE1)", "HOLEEMPTY(HOLE2)"]
        api("PUT", "/api/regime", {"regime": "free"})
        for i, texts in enumerate((APPROACH, ["TASK extract_peg(peg, HOLE1)"])):
            before = len(api("GET", "/api/sent")["items"])
            for text in texts:
                api("POST", "/api/program/insert", {"text": text})
            api("POST", "/api/submit", {"start": 0, "stop": len(texts)})
            sent = wait_for(lambda: (s := api("GET", "/api/sent"))["pending"] == 0 and len(s["items"]) == before + len(texts) and s,
                            60, 0.1, "the piece final")
            if i == 0:
                assert all(s["status"] == "done" for s in sent["items"][before:])
                wait_for(lambda: [a["action"] for a in api("GET", "/api/task")["robot_actions"]] == ["grasp(PEG)"],
                         20, 0.1, "the robot's grasp recognised")
        assert sent["items"][-1]["status"] == "failed" and "stuck" in sent["items"][-1]["reason"]
        task = wait_for(lambda: (t := api("GET", "/api/task"))["deviations"] and t, 20, 0.1, "a task deviation")
        deviation = task["deviations"][0]
        assert deviation["kind"] == "missing" and deviation["expected"] == "part(PEG,HOLE1)"
        assert deviation["status"] == "failed" and deviation["statement"] == sent["items"][-1]["number"]
        assert deviation["observed"]["PEGINHOLE(PEG,HOLE1)"] is True and deviation["observed"]["HOLEEMPTY(HOLE1)"] is False
        assert [a["action"] for a in task["robot_actions"]] == ["grasp(PEG)"]
        assert "HOLDING(PEG)" in task["robot_marking"] and "PEGINHOLE(PEG,HOLE1)" in task["robot_marking"]
        wait_for(lambda: any(e.get("task", {}).get("deviations") for e in seen), 10, 0.1, "the deviation on /api/events")
    finally:
        ws.close()
        stop_process(console.proc)
