"""``teleprog up`` owns its children: the telerobot and the link it started answer while the
console runs and are gone once the console is stopped with SIGTERM. What it prints is for a
newcomer: one URL to open, and no retry noise while the robot and the link start."""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import threading
import time

import httpx

from support import PROJECT_DIR, free_port, start_console, stop_process, wait_for


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
        health = httpx.get(f"http://127.0.0.1:{robot_port}/health", timeout=5).json()
        assert health["status"] == "ok"  # the robot listens before its core is built (--listen-first) ...
        wait_for(lambda: httpx.get(f"http://127.0.0.1:{robot_port}/health", timeout=5).json()["core_ready"],
                 timeout=60, what="the robot's core")  # ... and says when it is ready
        assert _listening(link_port)
        assert log.count("open http://") == 1
        link = running.api("GET", "/api/link").json()
        assert link["configured"] and link["url"] is None  # the address only to the holder of control
        grant = running.api("POST", "/api/control/request", headers={"X-Teleprog-Client": "ops"}).json()
        holder = {"X-Teleprog-Client": "ops", "X-Teleprog-Token": grant["token"]}
        assert running.api("GET", "/api/link", headers=holder).json()["url"] == f"ws://127.0.0.1:{link_port}"
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


RETRY_NOISE = re.compile(r"unreachable|retry|retrying|still down|Connect call failed|refused", re.IGNORECASE)


def test_up_prints_one_url_and_no_retries_while_starting(tmp_path) -> None:
    """The real ``teleprog up`` on free ports: stdout read line by line until the console's URL;
    it is the only ``http://`` URL there (no viser banner with viser's private port), the wait for
    the robot is said once, and neither stream logs a connection retry while robot and link start."""
    port, robot_port, link_port = free_port(), free_port(), free_port()
    err_path = tmp_path / "stderr.log"
    with err_path.open("w") as err:
        proc = subprocess.Popen(
            [sys.executable, "-m", "server.cli", "up", "--port", str(port), "--robot-port", str(robot_port),
             "--link-port", str(link_port), "--delay-ms", "100"],
            stdout=subprocess.PIPE, stderr=err, text=True, cwd=PROJECT_DIR, env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
    lines: list[str] = []
    ready = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if "open http://" in line:
                ready.set()
        ready.set()  # stdout closed: the process ended

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert ready.wait(150), f"no URL within 150 s; stdout so far: {lines}"
        assert proc.poll() is None, f"teleprog up exited {proc.returncode}:\n{''.join(lines)}\n{err_path.read_text()}"
        assert lines[-1].strip() == f"teleprog console: open http://127.0.0.1:{port}/"
        wait_for(lambda: httpx.get(f"http://127.0.0.1:{port}/api/link", timeout=5).json()["status"] == "live",
                 60, 0.2, "the console connected to the robot through the link")
    finally:
        stop_process(proc)
        reader.join(timeout=10)
    out, err_text = "".join(lines), err_path.read_text()
    assert proc.returncode == 0, out + err_text
    assert out.count("http://") == 1, out  # the console's URL, nothing else (viser's banner silenced)
    assert f":{port}/" in out and "Websocket" not in out
    assert out.count("waiting for the telerobot and the link") == 1, out
    assert f"telerobot ws://127.0.0.1:{robot_port}, link ws://127.0.0.1:{link_port}" in out
    noise = [line for line in (out + err_text).splitlines() if RETRY_NOISE.search(line)]
    assert not noise, "retry lines while starting:\n" + "\n".join(noise)
    # each retry would open a connection: the console's two channels at the link, the link's two at the robot
    assert err_text.count("connection open") <= 4, err_text


def test_a_child_that_cannot_listen_ends_up_with_one_clear_line(tmp_path) -> None:
    """The telerobot is started before the console's imports (``server.up.early``); when its port
    is taken it exits, and ``teleprog up`` says so in one line and stops the link it started."""
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        robot_port, link_port = busy.getsockname()[1], free_port()
        out = subprocess.run(
            [sys.executable, "-m", "server.cli", "up", "--port", "0", "--no-record", "--robot-port", str(robot_port),
             "--link-port", str(link_port)],
            capture_output=True, text=True, timeout=120, cwd=PROJECT_DIR,
        )
    assert out.returncode == 1, out.stderr
    assert "teleprog: error: the telerobot exited with code 1 before listening" in out.stderr
    assert "Traceback" not in out.stderr
    assert not _listening(link_port)
