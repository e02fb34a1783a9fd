"""What the console sends on the operator's behalf, through its HTTP API against real processes
(``teleprog up --delay-ms 200``: console, link and telerobot): in the free regime a generated
motion that would collide in the cell's model is held back with its reason, one that is clear
streams; after a contact fault, "back away" aborts and sends one slow motion out of the contact."""

from __future__ import annotations

import json
import math
import threading
from collections.abc import Iterator

import pytest
from websockets.sync.client import connect

from support import RunningConsole, start_console, stop_process, wait_for

HOME_J2_DEG = -45.52  # assets/cells/peg_in_hole.toml
CLIENT = {"X-Teleprog-Client": "page-safety"}


@pytest.fixture(scope="module")
def up(tmp_path_factory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("page-safety"), "--delay-ms", "200")
    try:
        yield running
    finally:
        stop_process(running.proc)


def call(up: RunningConsole, method: str, path: str, body: object | None = None, status: int = 200):
    r = up.api(method, path, headers=CLIENT, **({"json": body} if body is not None else {}))
    assert r.status_code == status, f"{method} {path}: {r.status_code} {r.text}"
    return r.json()


class Notices:
    """The notices of /api/events, read on a thread."""

    def __init__(self, up: RunningConsole) -> None:
        self.ws = connect(up.url.replace("http", "ws") + "/api/events", max_size=None)
        self.messages: list[str] = []
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        try:
            for raw in self.ws:
                event = json.loads(raw)
                if event.get("type") == "notice":
                    self.messages.append(event["message"])
        except Exception:  # noqa: BLE001 - closed at the end of the test
            pass

    def close(self) -> None:
        self.ws.close()


def fresh(up: RunningConsole) -> None:
    """Linked, nothing pending, the robot idle, the virtual arm where the robot is."""
    wait_for(lambda: call(up, "GET", "/api/link")["connected"], 30, what="the link")
    call(up, "POST", "/api/robot/abort")
    wait_for(lambda: call(up, "GET", "/api/sent")["pending"] == 0, 30, what="nothing pending")
    wait_for(lambda: call(up, "GET", "/api/remote")["state"] == "idle", 30, what="the robot idle")
    call(up, "POST", "/api/resync")
    call(up, "POST", "/api/program/load", {"text": "", "filename": "empty.tp"})


def test_free_regime_holds_back_a_generated_motion_that_would_collide(up: RunningConsole) -> None:
    fresh(up)
    notices = Notices(up)
    try:
        call(up, "PUT", "/api/regime", {"regime": "free"})
        call(up, "PUT", "/api/program/auto", {"on": True})
        sent_before = len(call(up, "GET", "/api/sent")["items"])
        # J2 from home to -36 deg puts the gripper into the plate (finding 12's arm)
        q2 = call(up, "GET", "/api/state")["q_deg"][1]
        call(up, "POST", "/api/jog/joint", {"joint": 2, "delta_deg": -36.0 - q2})
        call(up, "POST", "/api/jog/release")
        program = call(up, "GET", "/api/program")
        assert [e["text"] for e in program["entries"]] == ["DRIVE J2 TO -36 deg", ""]
        held = wait_for(lambda: [m for m in notices.messages if m.startswith("held back")], what="a held-back notice")
        assert "statement 1 (DRIVE J2 TO -36 deg): link6 touches plate" in held[0], held
        assert len(call(up, "GET", "/api/sent")["items"]) == sent_before  # nothing left the console
        # undone and driven the other way, clear of everything: it streams
        call(up, "POST", "/api/program/undo")
        q2 = call(up, "GET", "/api/state")["q_deg"][1]
        call(up, "POST", "/api/jog/joint", {"joint": 2, "delta_deg": -50.0 - q2})
        call(up, "POST", "/api/jog/release")
        sent = call(up, "GET", "/api/sent")["items"][sent_before:]
        assert [s["text"] for s in sent] == ["DRIVE J2 TO -50 deg"], (notices.messages, call(up, "GET", "/api/program"))
        wait_for(lambda: call(up, "GET", "/api/sent")["pending"] == 0, 30, what="the streamed motion final")
        assert call(up, "GET", "/api/sent")["items"][-1]["status"] == "done"
    finally:
        notices.close()
        call(up, "PUT", "/api/program/auto", {"on": False})
        call(up, "PUT", "/api/regime", {"regime": None})


def test_back_away_after_a_contact_fault(up: RunningConsole) -> None:
    fresh(up)
    refused = up.api("POST", "/api/robot/back_away", headers=CLIENT)
    assert refused.status_code == 409 and "fault" in refused.json()["detail"]
    # straight down into the plate beside the holes: the robot stops on the contact
    call(up, "PUT", "/api/regime", {"regime": "free"})
    for text in ("DRAW TO (40, 0, 120) mm IN WORK", "DRAW TO (40, 0, 20) mm IN WORK WITH SPEED 20 mm/s", "EVENT after"):
        call(up, "POST", "/api/program/insert", {"text": text})
    call(up, "POST", "/api/submit", {"start": 0, "stop": 3})
    wait_for(lambda: call(up, "GET", "/api/remote")["state"] == "fault", 30, what="the contact fault")
    sent = call(up, "GET", "/api/sent")["items"]
    assert sent[-2]["status"] == "failed" and sent[-1]["status"] not in ("done", "failed")
    # the physical arm brakes to a stop after the fault: read where it rests, as back away will
    last: list = []

    def resting() -> list | None:
        p = [row[3] for row in call(up, "GET", "/api/remote")["world_T_tcp"][:3]]
        steady = bool(last) and math.dist(p, last[-1]) < 1e-7
        last.append(p)
        return p if steady else None

    fault_p = wait_for(resting, 30, what="the arm at rest after the fault")

    before = len(sent)
    call(up, "POST", "/api/robot/back_away")
    final = wait_for(lambda: (s := call(up, "GET", "/api/sent"))["pending"] == 0 and s, 30, what="back away final")
    items = final["items"]
    assert items[before - 1]["status"] == "aborted"  # what was left was aborted first
    (motion,) = items[before:]
    assert motion["number"] is not None  # the robot took it
    assert motion["statement"]["kind"] == "DRAW" and motion["statement"]["frame"] == "WORLD"
    assert motion["statement"]["speed"] == {"value": pytest.approx(0.01), "unit": "m/s"}
    target = motion["statement"]["position"]
    # 30 mm straight back along the approach, which went straight down
    assert math.dist(target, fault_p) == pytest.approx(0.03, abs=1e-6)
    assert target[2] - fault_p[2] == pytest.approx(0.03, abs=1e-3)
    assert motion["status"] == "done", motion
    remote = call(up, "GET", "/api/remote")
    assert remote["world_T_tcp"][2][3] == pytest.approx(fault_p[2] + 0.03, abs=2e-3)
