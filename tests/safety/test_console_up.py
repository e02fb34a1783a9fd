"""``teleprog up`` as an operator meets it when something behind the console goes wrong.

The console with its own telerobot and link children (real processes, loopback WebSockets):

* the link frozen (SIGSTOP): ``/api/link`` says the robot is ``silent`` with a growing age and
  telemetry ``stale`` (no robot state read from old data) past the 1.2 s silence contract on the
  console's own clock, and ``live`` again after SIGCONT;
* the telerobot child killed while statements are queued: ``teleprog up`` reaps it, says so in
  ``/api/link`` and starts it again on its port; the console reconnects to the new robot
  session, the old statements read ``unknown`` in the sent list, and a new submission runs to done.

The silence checks hold whether or not the robot sends heartbeats: a frozen link carries nothing.
"""

from __future__ import annotations

import os
import re
import signal
import threading
import time
from pathlib import Path

import httpx
import pytest

from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S
from support import (
    LOADED_MACHINE_MARGIN_S,
    SILENCE_CONTRACT_S,
    RunningConsole,
    reported_silence_s,
    start_console,
    stop_process,
    wait_for,
)

CLIENT = {"X-Teleprog-Client": "safety"}


def _child_pid(console: RunningConsole, command: str) -> int:
    """The pid of the console's ``teleprog <command>`` child."""
    pid = console.proc.pid
    # every thread's children: the watch restarts a child from a thread of its own
    children = [c for task in Path(f"/proc/{pid}/task").iterdir() for c in (task / "children").read_text().split()]
    for child in children:
        argv = Path(f"/proc/{child}/cmdline").read_bytes().split(b"\0")
        if b"server.cli" in argv and command.encode() in argv:
            return int(child)
    raise AssertionError(f"no {command} child of the console (pid {pid}) among {children}")


def _zombie(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except FileNotFoundError:
        return False


def _api(console: RunningConsole, method: str, path: str, body: object | None = None) -> dict:
    r = console.api(method, path, headers=CLIENT, **({"json": body} if body is not None else {}))
    assert r.status_code == 200, f"{method} {path}: {r.status_code} {r.text}"
    return r.json()


def _link(console: RunningConsole) -> dict:
    return _api(console, "GET", "/api/link")


def _ports(console: RunningConsole) -> tuple[int, int]:
    pattern = re.compile(r"telerobot ws://127\.0\.0\.1:(\d+), link ws://127\.0\.0\.1:(\d+)")
    m = wait_for(lambda: pattern.search(console.log_path.read_text()), 60, 0.1, "the children's ports in the log")
    return int(m[1]), int(m[2])


def _drive_running(console: RunningConsole, speed_pct: float, degrees: float):
    """A live link, the free regime, and a slow drive of joint 1 by ``degrees`` at ``speed_pct``
    submitted and running on the robot; returns a reader of the robot's own ``/health`` (no delay)."""
    robot_port, _ = _ports(console)
    wait_for(lambda: _link(console)["status"] == "live", 60, 0.1, "a live link")
    health = lambda: httpx.get(f"http://127.0.0.1:{robot_port}/health", timeout=5).json()  # noqa: E731
    _api(console, "PUT", "/api/regime", {"regime": "free"})
    q = _api(console, "GET", "/api/arm")["q_deg"]
    for text in (f"SPEED {speed_pct:g} %", f"DRIVE J1 TO {q[0] + degrees:.2f} deg"):
        _api(console, "POST", "/api/program/insert", {"text": text})
    _api(console, "POST", "/api/submit", {"start": 0, "stop": 2})
    wait_for(lambda: health()["state"] == "running", 20, 0.05, "the drive running on the robot")
    return health


def test_frozen_link_shows_silent_and_stale_then_live_again(tmp_path) -> None:
    console = start_console(tmp_path, "--delay-ms", "100")
    link_pid = None
    try:
        _ports(console)
        wait_for(lambda: (v := _link(console))["status"] == "live" and v["telemetry"] == "live", 60, 0.1, "a live link")
        link_pid = _child_pid(console, "link")
        os.kill(link_pid, signal.SIGSTOP)
        live: list[dict] = []  # the views that still said live after the freeze

        def silent() -> dict | None:
            v = _link(console)
            if v["status"] == "silent":
                return v
            live.append(v)
            return None

        view = wait_for(silent, SILENCE_CONTRACT_S + LOADED_MACHINE_MARGIN_S, 0.05, "the link shown silent")
        # on the console's own clock (status and age are read at one instant): live up to the
        # contract's 1.2 s of silence, silent beyond it, however late the polls came
        assert view["silence_limit_s"] == DEFAULT_SILENCE_LIMIT_S
        assert view["heard_ago_s"] >= SILENCE_CONTRACT_S
        assert all(v["status"] == "live" and v["heard_ago_s"] <= SILENCE_CONTRACT_S for v in live), live
        assert view["connected"] is True  # the socket is open: silence, not a cut
        later = wait_for(lambda: (v := _link(console))["heard_ago_s"] > view["heard_ago_s"] + 0.5 and v, 5, 0.1,
                         "the silence age growing")
        assert later["status"] == "silent"
        assert later["telemetry"] == "stale" and later["robot_state"] is None  # never an old state read as now
        assert any("silent" in p for p in later["problems"]) and any("stale" in p for p in later["problems"])
        os.kill(link_pid, signal.SIGCONT)
        link_pid = None
        wait_for(lambda: (v := _link(console))["status"] == "live" and v["telemetry"] == "live", 10, 0.1,
                 "the link live again after SIGCONT")
    finally:
        if link_pid is not None:
            os.kill(link_pid, signal.SIGCONT)
        stop_process(console.proc)


def test_killed_robot_child_is_restarted_and_old_statements_read_unknown(tmp_path) -> None:
    console = start_console(tmp_path, "--delay-ms", "50")
    try:
        robot_port, _ = _ports(console)
        wait_for(lambda: _link(console)["status"] == "live", 60, 0.1, "a live link")
        session_before = _link(console)["robot_session"]
        _api(console, "PUT", "/api/regime", {"regime": "free"})
        q = _api(console, "GET", "/api/arm")["q_deg"]
        for text in ("SPEED 5 %", f"DRIVE J1 TO {q[0] + 30:.2f} deg", f"DRIVE J1 TO {q[0]:.2f} deg",
                     f"DRIVE J1 TO {q[0] + 30:.2f} deg"):
            _api(console, "POST", "/api/program/insert", {"text": text})
        _api(console, "POST", "/api/submit", {"start": 0, "stop": 4})
        wait_for(lambda: any(s["status"] == "running" for s in _api(console, "GET", "/api/sent")["items"]), 20, 0.05,
                 "a statement running")
        robot_pid = _child_pid(console, "robot")
        os.kill(robot_pid, signal.SIGKILL)
        restarted = wait_for(
            lambda: (v := _link(console))["children"].get("telerobot", "").startswith("running (restarted") and v, 60, 0.1,
            "teleprog up saying it restarted the telerobot",
        )
        assert "last exit -9" in restarted["children"]["telerobot"]
        assert not _zombie(robot_pid) and not Path(f"/proc/{robot_pid}").exists()  # reaped
        assert _child_pid(console, "robot") != robot_pid
        health = httpx.get(f"http://127.0.0.1:{robot_port}/health", timeout=5).json()  # the same port
        assert health["status"] == "ok"
        view = wait_for(lambda: (v := _link(console))["robot_restarts"] == 1 and v["status"] == "live" and v, 30, 0.1,
                        "the console on the new robot session")
        assert view["robot_session"] != session_before
        sent = _api(console, "GET", "/api/sent")
        assert sent["pending"] == 0
        unknown = [s for s in sent["items"] if s["status"] == "unknown"]
        assert unknown and all("robot restarted" in s["reason"] and "unknown" in s["reason"] for s in unknown)
        assert all(s["status"] in ("done", "unknown") for s in sent["items"])
        # a new submission is accepted by the new robot (numbered from 1) and runs
        _api(console, "POST", "/api/program/insert", {"text": "EVENT after_restart"})
        program = _api(console, "GET", "/api/program")
        _api(console, "POST", "/api/submit", {"start": 0, "stop": program["empty_index"]})
        done = wait_for(lambda: (s := _api(console, "GET", "/api/sent"))["pending"] == 0 and s["items"][-1]["status"] == "done"
                        and s, 30, 0.1, "the new submission done")
        assert done["items"][-1]["number"] >= 1 and done["items"][-1]["text"].startswith("EVENT")
        assert httpx.get(f"http://127.0.0.1:{robot_port}/health", timeout=5).json()["numbered"] == len(
            [s for s in done["items"] if s["submitted_at"] >= done["items"][-1]["submitted_at"]])
    finally:
        stop_process(console.proc)
    assert console.proc.returncode == 0


def test_a_frozen_console_halts_the_robot_within_the_limit_and_resume_continues(tmp_path) -> None:
    """The console frozen behind a live link (the link keeps both sockets open): the robot hears
    no heartbeat, stops the running statement within the silence limit and says why; after the
    console thaws it shows the halt, and the operator's resume lets the statement finish."""
    console = start_console(tmp_path, "--delay-ms", "100")
    frozen = False
    try:
        health = _drive_running(console, speed_pct=3, degrees=40)
        os.kill(console.proc.pid, signal.SIGSTOP)
        frozen = True
        held = wait_for(lambda: (h := health())["state"] == "stopped" and h, SILENCE_CONTRACT_S + LOADED_MACHINE_MARGIN_S,
                        0.05, "the robot stopped by silence")
        # on the robot's own servo clock: it halted at the contract's 1.2 s of silence (its report
        # has 0.1 s steps), whatever the load did to the test's polling
        assert reported_silence_s(held["halted"]) == pytest.approx(SILENCE_CONTRACT_S, abs=0.05), held["halted"]
        time.sleep(0.5)  # the arm holds: the statement is still current, not finished
        assert health()["state"] == "stopped" and health()["current"] == held["current"] != 0
        os.kill(console.proc.pid, signal.SIGCONT)
        frozen = False
        view = wait_for(lambda: (v := _link(console))["status"] == "live" and v["halted"] and v, 15, 0.1,
                        "the console showing the robot's halt")
        assert "no message from the console" in view["halted"]
        _api(console, "POST", "/api/robot/resume")
        wait_for(lambda: (v := _link(console))["halted"] is None, 15, 0.1, "the halt cleared by the resume")
        done = wait_for(lambda: (s := _api(console, "GET", "/api/sent"))["pending"] == 0 and s, 60, 0.2,
                        "the drive finished after resume")
        assert [s["status"] for s in done["items"]] == ["done", "done"]
    finally:
        if frozen:
            os.kill(console.proc.pid, signal.SIGCONT)
        stop_process(console.proc)


def test_a_stalled_session_neither_silences_the_link_nor_delays_a_stop(tmp_path) -> None:
    """The session's work stalls for 5 s (``/api/faults/stall``: a computation holding the
    session's lock, as a slow plan does) while the robot runs a drive: the heartbeats go on, so
    the robot never halts for silence, and a STOP pressed during the stall reaches the robot
    within the link's delay (plus the test's polling on a loaded machine), long before the stall ends."""
    delay_s, stall_s = 0.3, 5.0
    console = start_console(tmp_path, "--delay-ms", str(delay_s * 1e3), "--fault-injection")
    try:
        health = _drive_running(console, speed_pct=3, degrees=40)
        assert _api(console, "POST", "/api/faults/stall", {"seconds": stall_s})["started"]
        stalled_at = time.monotonic()
        # twice the silence contract with the session stalled: the robot still hears the console
        while time.monotonic() < stalled_at + 2 * SILENCE_CONTRACT_S:
            h = health()
            assert h["state"] == "running" and h["halted"] is None, f"the robot halted during the stall: {h}"
            time.sleep(0.05)
        # STOP during the stall: neither the command nor its answer waits for the session
        answer: dict = {}
        stopping = threading.Thread(target=lambda: answer.update(r=console.api("POST", "/api/robot/stop", headers=CLIENT)))
        stopping.start()
        # the link's one-way delay to the robot, plus the test's polling on a loaded machine
        wait_for(lambda: health()["state"] == "stopped", delay_s + LOADED_MACHINE_MARGIN_S, 0.02, "the robot stopped by the STOP")
        assert time.monotonic() < stalled_at + stall_s, "the STOP waited for the stalled session"
        assert health()["halted"] is None  # stopped by the operator's STOP, never halted for silence
        # the console shows it acknowledged after the round trip, the session still stalled: the
        # link's view and the acknowledgement need no session lock
        wait_for(lambda: not _link(console)["recovery_pending"], 2 * delay_s + LOADED_MACHINE_MARGIN_S, 0.02,
                 "the STOP acknowledged during the stall")
        assert time.monotonic() < stalled_at + stall_s, "the STOP's acknowledgement waited for the stalled session"
        stopping.join(stall_s + 30)
        assert answer["r"].status_code == 200, answer["r"].text
        # after the stall (the console takes the submission's answer, held by the stall, then):
        # the drive held, not failed by silence
        time.sleep(max(0.0, stalled_at + stall_s - time.monotonic()))
        wait_for(lambda: _api(console, "GET", "/api/sent")["items"][-1]["status"] != "sending", 15, 0.1,
                 "the submission's answer taken after the stall")
        sent = _api(console, "GET", "/api/sent")["items"]
        assert sent[-1]["status"] in ("running", "received"), sent[-1]
    finally:
        stop_process(console.proc)


def test_a_long_load_and_a_long_submit_never_silence_the_running_robot(tmp_path) -> None:
    """Issue 35: a 20,000-line program loaded and 1,000 statements submitted while the robot runs
    a drive, over a 300 ms link: the console's own work never holds its heartbeats, so the robot
    never halts for silence (its ``/health`` polled throughout, with no delay)."""
    console = start_console(tmp_path, "--delay-ms", "300")
    try:
        health = _drive_running(console, speed_pct=1, degrees=60)  # outlasts both loads
        seen: list[dict] = []
        done = threading.Event()

        def poll() -> None:
            while not done.is_set():
                seen.append(health())
                time.sleep(0.05)

        watcher = threading.Thread(target=poll, daemon=True)
        watcher.start()
        try:
            for lines in (20_000, 1_000):
                text = "".join(f"DRIVE J1 TO {(-1) ** i * 0.5:.1f} deg\n" for i in range(lines))
                r = httpx.post(console.url + "/api/program/upload", params={"filename": "long.tp"}, content=text.encode(),
                               headers={**CLIENT, "content-type": "text/plain"}, timeout=120)
                assert r.status_code == 200 and len(r.json()["entries"]) == lines + 1, r.text[:300]
            r = httpx.post(console.url + "/api/submit", json={"start": 0, "stop": 1_000}, headers=CLIENT, timeout=120)
            assert r.status_code == 200 and len(r.json()["items"]) >= 1_002, r.text[:300]
            wait_for(lambda: health()["queued"] >= 1_000, 30, 0.1, "the robot holding the 1,000 statements")
            time.sleep(2 * SILENCE_CONTRACT_S)  # the console's work after the answer: what the robot hears meanwhile
        finally:
            done.set()
            watcher.join(10)
        assert seen and all(h["halted"] is None for h in seen), next(h for h in seen if h["halted"] is not None)
        assert {h["state"] for h in seen} == {"running"}, {h["state"] for h in seen}
    finally:
        stop_process(console.proc)


def test_fault_injection_is_off_unless_asked(tmp_path) -> None:
    from fastapi.testclient import TestClient

    from server.app import create_app
    from server.settings import ConsoleSettings

    with TestClient(create_app(ConsoleSettings(no_robot=True, record=False), build_page=False)) as client:
        assert client.post("/api/faults/stall", json={"seconds": 1}).status_code == 404
