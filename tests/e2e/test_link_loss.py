"""Losing the link loses nothing: telerobot, link and console as separate real processes; the
link is killed while a submission is in flight and started again on the same port; every
statement then runs exactly once and reaches done, and the console said the link was down."""

from __future__ import annotations

import time

import httpx

from server.up.stack import start_child, stop_child
from support import start_console, stop_process, wait_for

CLIENT = {"X-Teleprog-Client": "trial"}


def _wait(what: str, predicate, timeout: float = 40.0):
    return wait_for(predicate, timeout, 0.05, what)


def test_cut_link_loses_nothing_and_runs_nothing_twice(tmp_path) -> None:
    # the cut and the link's restart last seconds, past the silence limit that would stop the arm
    # (tested in tests/safety): this test is about exactly-once across the cut
    robot = start_child("telerobot", ["robot", "--port", "0", "--silence-limit-s", "30"], 60)
    link = start_child("link", ["link", "--port", "0", "--robot", robot.url, "--delay-ms", "200"], 60)
    link_port = link.url.rsplit(":", 1)[1]
    console = None
    try:
        console = start_console(tmp_path, "--robot-url", link.url)

        def api(method: str, path: str, body: object | None = None) -> dict:
            r = console.api(method, path, headers=CLIENT, **({"json": body} if body is not None else {}))
            assert r.status_code == 200, f"{method} {path}: {r.status_code} {r.text}"
            return r.json()

        _wait("the link", lambda: api("GET", "/api/link")["connected"])
        api("PUT", "/api/regime", {"regime": "free"})
        q = api("GET", "/api/arm")["q_deg"]
        for text in ("SPEED 50 %", f"DRIVE J1 TO {q[0] + 15:.2f} deg", f"DRIVE J2 TO {q[1] - 5:.2f} deg",
                     f"DRIVE J1 TO {q[0]:.2f} deg", "EVENT back"):
            api("POST", "/api/program/insert", {"text": text})
        api("POST", "/api/submit", {"start": 0, "stop": 5})
        time.sleep(0.1)  # the communication is inside the delayed link now
        stop_child(link)
        _wait("the console to see the link down", lambda: not api("GET", "/api/link")["connected"])
        time.sleep(0.5)
        link = start_child("link", ["link", "--port", link_port, "--robot", robot.url, "--delay-ms", "200"], 60)
        sent = _wait("every statement final", lambda: (s := api("GET", "/api/sent"))["pending"] == 0 and s)
        assert [s["status"] for s in sent["items"]] == ["done"] * 5
        assert sorted(s["number"] for s in sent["items"]) == [1, 2, 3, 4, 5]
        health = httpx.get(robot.url.replace("ws://", "http://") + "/health", timeout=5).json()
        assert health["numbered"] == 5  # the robot numbered each statement once: nothing resent as new
        link_view = api("GET", "/api/link")
        assert link_view["connected"] and link_view["reconnects"] >= 1
    finally:
        if console is not None:
            stop_process(console.proc)
        stop_child(link)
        stop_child(robot)
