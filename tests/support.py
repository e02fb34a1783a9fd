"""Test helpers shared by fixtures and tests: free ports, the console as a real process."""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import httpx
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect as connect_ws

from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S, HEARTBEAT_INTERVAL_S

PROJECT_DIR = Path(__file__).resolve().parent.parent
ARTIFACTS = PROJECT_DIR / "test-artifacts"

CHROMIUM_ARGS = [
    "--no-sandbox",
    "--enable-unsafe-swiftshader",
    "--use-angle=swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
]


T = TypeVar("T")


def robot_headers() -> dict[str, str]:
    """The upgrade headers that present the tests' robot credential (conftest sets it for every
    process the tests start; ``shared.wire.credential``)."""
    from shared.wire.credential import ENV_VAR, headers

    return headers(os.environ[ENV_VAR])


def screenshot_if_failed(request, page) -> None:
    """After a test (``request`` is its fixture request), keep a screenshot of the Playwright
    ``page`` in ARTIFACTS when the test's call failed (see conftest's report hook)."""
    report = getattr(request.node, "rep_call", None)
    if report is not None and report.failed:
        ARTIFACTS.mkdir(exist_ok=True)
        page.screenshot(path=str(ARTIFACTS / f"{request.node.name}.png"))


SILENCE_CONTRACT_S = HEARTBEAT_INTERVAL_S + DEFAULT_SILENCE_LIMIT_S
"""The silence contract (``shared.wire.liveness``): an end that has heard nothing for the heartbeat
interval (0.2 s) plus the silence limit (1.0 s), 1.2 s, calls the other silent, and a robot that
hears nothing that long from its console halts. Held to this figure exactly where the robot or the
console reports the silence it measured on its own clock."""
LOADED_MACHINE_MARGIN_S = 3.0
"""What a test's own wall clock may add to a contract's figure when it can only time from outside
(SIGSTOP, then polling): the polls' interval and HTTP round trips, and on a loaded 2-core machine
(fresh-clone runs measured load 20-35) seconds of a process waiting for a core. Named once, so
no test widens a contract on its own."""
SLOWDOWN = float(os.environ.get("TELEPROG_TEST_SLOWDOWN") or 1.0)
"""Scales the suite's waits on a page for a loaded machine (``TELEPROG_TEST_SLOWDOWN=3`` on a busy
box): one setting for every browser test, never a test's own bound."""
PAGE_WAIT_S = 60.0 * SLOWDOWN
"""How long a page may take to show a change (software WebGL on a loaded 2-core machine draws a
frame in up to seconds); what a test waits on is the change itself, this only bounds the wait."""
DRAG_EFFECT_S = 20.0 * SLOWDOWN
"""How long a drag's effect (the arm moving) may take to reach the session before the drag counts
as a miss (the press found no handle): only then is the next grab point tried, so a slow page
never gets the same drag twice."""
PAGE_DPR = os.environ.get("TELEPROG_TEST_DPR") or "0.5"
"""The resolution the tests' pages draw their 3D view at (viser's ``fixedDpr``: canvas pixels per
CSS pixel). Headless Chromium draws WebGL in software, where a frame's cost is mostly per pixel:
at 0.5 an idle page's redraws took 0.09 of a core against 0.21 at 1 (measured with the
environment map already gone). Clicks, drags and the page's layout are in CSS pixels, so nothing
a test does or reads changes; ``TELEPROG_TEST_DPR=1`` draws at full resolution."""
_SILENCE_REPORT = re.compile(r"no message from the console for (\d+(?:\.\d+)?) s")


def reported_silence_s(halted: str) -> float:
    """The silence (s, on the robot's servo clock, to its report's 0.1 s) a robot's silence halt
    says it measured: ``no message from the console for 1.2 s (limit ...)``."""
    m = _SILENCE_REPORT.search(halted or "")
    assert m, f"not a silence halt: {halted!r}"
    return float(m[1])


def wait_for(predicate: Callable[[], T], timeout: float = 15.0, interval: float = 0.1, what: str = "condition") -> T:
    """Poll ``predicate`` until it returns something truthy and return that; fail saying
    ``what`` was not met within ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"{what} not met within {timeout:g} s")
        time.sleep(interval)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_http(url: str, proc: subprocess.Popen | None = None, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc is not None and proc.poll() is not None:
            raise RuntimeError(f"process exited with {proc.returncode} before {url} answered")
        try:
            if httpx.get(url, timeout=1.0).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    raise TimeoutError(f"{url} did not answer within {timeout} s")


class RunningConsole:
    def __init__(self, proc: subprocess.Popen, port: int, log_path: Path) -> None:
        self.proc = proc
        self.port = port
        self.url = f"http://127.0.0.1:{port}"
        self.log_path = log_path

    def api(self, method: str, path: str, **kwargs) -> httpx.Response:
        return httpx.request(method, self.url + path, timeout=10.0, **kwargs)

    def call(self, method: str, path: str, body: dict | None = None) -> dict:
        """``api`` for a call that must succeed: its JSON answer (fails the test on anything but 200)."""
        r = self.api(method, path, json=body)
        assert r.status_code == 200, f"{method} {path}: {r.status_code} {r.text}"
        return r.json()


def record_three_statements(console: RunningConsole) -> dict:
    """A short real session: SPEED, a 10 degree DRIVE of joint 1 (most of a second at 20 %) and
    an EVENT, submitted in the free regime once the link is live; returns the sent list once all
    three are final."""
    wait_for(lambda: console.call("GET", "/api/link")["status"] == "live", 60, 0.1, "a live link")
    console.call("PUT", "/api/regime", {"regime": "free"})
    q = console.call("GET", "/api/arm")["q_deg"]
    for text in ("SPEED 20 %", f"DRIVE J1 TO {q[0] + 10:.2f} deg", "EVENT recorded"):
        console.call("POST", "/api/program/insert", {"text": text})
    console.call("POST", "/api/submit", {"start": 0, "stop": 3})
    return wait_for(lambda: (s := console.call("GET", "/api/sent"))["pending"] == 0 and len(s["items"]) == 3 and s,
                    60, 0.1, "every statement final")


def child_env(env: dict[str, str | None] | None = None) -> dict[str, str]:
    """The tests' environment for a child process, with ``env`` set on top (None: removed)."""
    out = {**os.environ, "PYTHONUNBUFFERED": "1"}
    for key, value in (env or {}).items():
        if value is None:
            out.pop(key, None)
        else:
            out[key] = value
    return out


def start_console(tmp_path: Path, *extra: str, timeout: float = 180.0, name: str = "console",
                  env: dict[str, str | None] | None = None) -> RunningConsole:
    return start_served(tmp_path, "up", *extra, timeout=timeout, name=name, env=env)


def start_served(tmp_path: Path, command: str, *extra: str, timeout: float = 180.0, name: str = "console",
                 env: dict[str, str | None] | None = None) -> RunningConsole:
    """``teleprog COMMAND --port P EXTRA...`` (a console: ``up``, ``replay``) as a process, once
    its ``/api/health`` answers; its output goes to ``tmp_path/NAME.log``; ``env``: see ``child_env``."""
    port = free_port()
    log_path = tmp_path / f"{name}.log"
    log = log_path.open("w")
    proc = subprocess.Popen(
        [sys.executable, "-m", "server.cli", command, *extra, "--port", str(port)],
        stdout=log, stderr=subprocess.STDOUT, cwd=PROJECT_DIR, env=child_env(env),
    )
    try:
        wait_http(f"http://127.0.0.1:{port}/api/health", proc, timeout=timeout)
    except Exception:
        proc.kill()
        raise RuntimeError(f"teleprog {command} did not start:\n{log_path.read_text()}") from None
    return RunningConsole(proc, port, log_path)


def stop_process(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


class ServerProcess:
    """A ``teleprog <command>`` server as a real process on a fixed port, so a test can kill it
    (SIGKILL: nothing said goodbye, whatever was in flight is gone) and start it again."""

    def __init__(self, tmp_path: Path, command: str, *args: str, port: int | None = None, timeout: float = 120.0,
                 env: dict[str, str | None] | None = None) -> None:
        self.env = env
        self.port = port or free_port()
        self.command = command
        self.args = args
        self.timeout = timeout
        self.log_path = tmp_path / f"{command}-{self.port}.log"
        self.proc: subprocess.Popen | None = None

    def start(self):
        log = self.log_path.open("a")
        verbose = ["-v"] if os.environ.get(f"{self.command.upper()}_VERBOSE") else []
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "server.cli", *verbose, self.command, "--port", str(self.port), *self.args],
            stdout=log, stderr=subprocess.STDOUT, cwd=PROJECT_DIR, env=child_env(self.env),
        )
        try:
            wait_http(f"http://127.0.0.1:{self.port}/health", self.proc, timeout=self.timeout)
        except Exception:
            self.kill()
            raise RuntimeError(f"{self.command} did not start:\n{self.log_path.read_text()}") from None
        return self

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}"

    def health(self) -> dict:
        return httpx.get(f"http://127.0.0.1:{self.port}/health", timeout=5).json()

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    def stop(self) -> int | None:
        if self.proc is not None:
            stop_process(self.proc)
        return self.proc.returncode if self.proc else None


class EventFeed:
    """The console's events of some kinds on ``/api/events`` as they arrive (``events``, parsed)
    and their arrival times (``times``, ``time.perf_counter``), read on a thread. Use as a context
    manager (or ``close()``); an error of the reader other than the socket closing is raised again
    by ``between`` and ``close``."""

    def __init__(self, console_url: str, kinds: str | tuple[str, ...] = "arm") -> None:
        self.kinds = (kinds,) if isinstance(kinds, str) else tuple(kinds)
        self.events: list[dict] = []
        self.times: list[float] = []
        self._error: BaseException | None = None
        self._ws = connect_ws(console_url.replace("http", "ws", 1) + "/api/events", max_size=None, compression=None)
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        try:
            for raw in self._ws:
                event = json.loads(raw)
                if event.get("type") in self.kinds:
                    self.times.append(time.perf_counter())
                    self.events.append(event)
        except ConnectionClosed:
            pass
        except Exception as exc:  # noqa: BLE001 - handed to the test by between() and close()
            self._error = exc

    def _check(self) -> None:
        if self._error is not None:
            raise RuntimeError(f"reading /api/events failed: {self._error!r}") from self._error

    def between(self, t0: float, t1: float) -> list[float]:
        self._check()
        return [t for t in self.times if t0 <= t <= t1]

    def close(self) -> None:
        self._ws.close()
        self._thread.join(timeout=5.0)
        self._check()

    def __enter__(self) -> "EventFeed":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
