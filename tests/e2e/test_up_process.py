"""``teleprog up`` owns its children: the telerobot and the link it started answer while the
console runs and are gone once the console is stopped with SIGTERM."""

from __future__ import annotations

import re
import socket
import time

import httpx

from support import start_console, stop_process


def _listening(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(1.0)
        return s.connect_ex(("127.0.0.1", port)) == 0


def test_up_starts_robot_and_link_and_stops_them(tmp_path) -> None:
    running = start_console(tmp_path, "--delay-ms", "200")
    try:
        pattern = re.compile(r"telerobot ws://127\.0\.0\.1:(\d+), link ws://127\.0\.0\.1:(\d+) \(200 ms each way\)")
        deadline = time.monotonic() + 60
        while not (m := pattern.search(log := running.log_path.read_text())) and time.monotonic() < deadline:
            time.sleep(0.1)  # the children start while the console does; the line comes when both listen
        assert m, log
        robot_port, link_port = int(m[1]), int(m[2])
        assert httpx.get(f"http://127.0.0.1:{robot_port}/health", timeout=5).json()["status"] == "ok"
        assert _listening(link_port)
        assert log.count("open http://") == 1
        link = running.api("GET", "/api/link").json()
        assert link["configured"] and link["url"] == f"ws://127.0.0.1:{link_port}"
    finally:
        stop_process(running.proc)  # SIGTERM
    assert running.proc.returncode == 0
    assert not _listening(robot_port) and not _listening(link_port)


def test_no_robot_is_console_only_and_says_so(tmp_path) -> None:
    running = start_console(tmp_path, "--no-robot")
    try:
        assert "console only (no robot)" in running.log_path.read_text()
        assert running.api("GET", "/api/link").json()["configured"] is False
        running.api("POST", "/api/program/insert", json={"text": "DRIVE J1 TO 5 deg"})
        r = running.api("POST", "/api/submit", json={"start": 0, "stop": 1})
        assert r.status_code == 409 and "--no-robot" in r.json()["detail"]
        assert running.api("GET", "/api/program").json()["empty_index"] == 1  # the statement stays
    finally:
        stop_process(running.proc)
    assert running.proc.returncode == 0
