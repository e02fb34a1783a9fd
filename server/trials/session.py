"""One trial run's whole session: ``teleprog up`` (telerobot, delayed link, console) as a child
process on a free port, and a small synchronous client of the console's HTTP API.

Each run gets its own session, so runs share nothing: a fresh robot whose world is seeded from
``--seed`` and the run index, with the trial's offsets, noise, tilt, friction and
clearance (``TELEPROG_ROBOT_WORLD__*``, read by the telerobot the session starts), a fresh link and a fresh console. Nothing is recorded (``--no-record``); the session's
output goes to a log file that an error names.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from robot_sim.settings import WorldSettings
from shared.errors import TeleprogError
from shared.paths import PROJECT_DIR

T = TypeVar("T")
CLIENT_LABEL = "teleprog trial"


class TrialError(TeleprogError):
    """A run could not go on (the session did not start, the link never came up, a wait ran out)."""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class ConsoleApi:
    """The console's HTTP API for one trial client; holds the control lock once ``take_control``."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.headers = {"X-Teleprog-Client": CLIENT_LABEL}
        import httpx  # here: the console imports this module at start and seldom runs a trial

        self._http = httpx.Client(base_url=url, timeout=10.0)

    def call(self, method: str, path: str, body: object | None = None) -> dict:
        r = self._http.request(method, path, json=body, headers=self.headers)
        if r.status_code != 200:
            raise TrialError(f"{method} {path} answered {r.status_code}: {r.text[:300]}")
        return r.json()

    def take_control(self) -> None:
        self.headers["X-Teleprog-Token"] = self.call("POST", "/api/control/request")["token"]

    def close(self) -> None:
        self._http.close()


def wait_until(predicate: Callable[[], T], timeout: float, what: str, period: float = 0.01) -> T:
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise TrialError(f"{what} not within {timeout:g} s")
        time.sleep(period)


def world_environment(world: WorldSettings) -> dict[str, str]:
    """The telerobot's settings for this world, as the environment ``teleprog robot`` reads."""
    return {f"TELEPROG_ROBOT_WORLD__{name.upper()}": repr(value) if isinstance(value, float) else str(value)
            for name, value in world.model_dump().items() if value is not None}


class TrialSession:
    """``teleprog up --delay-ms D --cell CELL --port P --no-record`` as a child, with its API.

    Use as a context manager: on entry the console answers and its link is live; on exit the
    session is stopped (SIGTERM, then SIGKILL)."""

    def __init__(self, *, delay_ms: float, cell: str | Path, world: WorldSettings, log_path: Path,
                 start_timeout: float = 180.0) -> None:
        self.delay_ms = delay_ms
        self.cell = str(cell)
        self.world = world
        self.log_path = log_path
        self.start_timeout = start_timeout
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.proc: subprocess.Popen | None = None
        self.api: ConsoleApi | None = None

    def __enter__(self) -> "TrialSession":
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        with self.log_path.open("w") as log:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "server.cli", "up", "--delay-ms", f"{self.delay_ms:g}", "--cell", self.cell,
                 "--port", str(self.port), "--no-record"],
                stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, cwd=PROJECT_DIR,
                env={**os.environ, "PYTHONUNBUFFERED": "1", **world_environment(self.world)},
            )
        try:
            self._wait_up()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def _wait_up(self) -> None:
        import httpx

        deadline = time.monotonic() + self.start_timeout
        while True:
            if self.proc is not None and self.proc.poll() is not None:
                raise TrialError(f"teleprog up exited with {self.proc.returncode} before it answered; see {self.log_path}")
            try:
                if httpx.get(self.url + "/api/health", timeout=1.0).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                raise TrialError(f"teleprog up did not answer within {self.start_timeout:g} s; see {self.log_path}")
            time.sleep(0.1)
        self.api = ConsoleApi(self.url)
        wait_until(lambda: self.api.call("GET", "/api/link")["status"] == "live", 60.0 + 2 * self.delay_ms / 1e3,
                   f"a live link to the telerobot (see {self.log_path})", period=0.05)

    def __exit__(self, *exc_info) -> None:
        if self.api is not None:
            self.api.close()
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
