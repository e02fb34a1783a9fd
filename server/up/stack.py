"""The processes behind ``teleprog up``: the telerobot and the delayed link as child processes.

Why children and not threads: the robot and the link are separate services in the product
(thesis §4.4: the console and the telerobot talk only over the delayed channels), and running
them as the very commands a user would type keeps ``teleprog up`` honest. Each child is started
with ``--json`` on a configured port or one chosen free; its first stdout line says where it
listens. Children get SIGTERM when the console stops (and, on Linux, when the console dies:
``PR_SET_PDEATHSIG``), so nothing is left running.

While the console runs, ``ChildWatch`` polls the children (which also reaps them: no zombie),
logs an exit once, starts the child again with the same arguments (so on the same port) unless
told not to, and says how each one is for the console's link view.
"""

from __future__ import annotations

import json
import logging
import os
import queue
import signal
import socket
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path

from shared.errors import InputError
from shared.wire.credential import ENV_VAR

log = logging.getLogger(__name__)

PROJECT_DIR = Path(__file__).resolve().parents[2]


def _die_with_parent() -> None:  # runs in the child before exec
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except Exception:  # noqa: BLE001 - not Linux: the console's finally still stops the child
        pass
    os.setsid()  # Ctrl-C reaches the console only; it stops the children in order


def free_port(host: str = "127.0.0.1") -> int:
    """A port the OS calls free now (another process could take it before the child binds it;
    the child then fails with a clear error)."""
    with socket.socket() as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


@dataclass
class Child:
    """A started child process; ``url`` is filled once it said where it listens."""

    name: str
    proc: subprocess.Popen
    args: list[str] = field(default_factory=list)
    env: dict[str, str] = field(default_factory=dict, repr=False)
    """Variables set for this child on top of the console's (the robot's credential): kept for a restart."""
    url: str = ""
    ready: dict = field(default_factory=dict)
    _lines: queue.Queue = field(default_factory=queue.Queue, repr=False)

    def wait_ready(self, timeout: float) -> "Child":
        """Wait for the child's ``--json`` line; raises ``InputError`` saying why it did not come."""
        if self.url:
            return self
        try:
            line = self._lines.get(timeout=timeout)
        except queue.Empty:
            stop_child(self)
            raise InputError(f"the {self.name} did not start listening within {timeout:g} s") from None
        if line is None:
            code = self.proc.wait()
            raise InputError(f"the {self.name} exited with code {code} before listening (its error is above)")
        try:
            self.ready = json.loads(line)
            self.url = str(self.ready["listening"])
        except (ValueError, KeyError, TypeError):
            stop_child(self)
            raise InputError(f"the {self.name} printed {line.strip()!r} instead of where it listens") from None
        return self


def spawn_child(name: str, args: list[str], env: dict[str, str] | None = None) -> Child:
    """Start ``teleprog <args> --json`` without waiting (see ``Child.wait_ready``); ``env``: variables
    set on top of the console's (passed in the environment, which only the same user can read)."""
    cmd = [sys.executable, "-m", "server.cli", *args, "--json"]
    env = dict(env or {})
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=None, text=True, cwd=PROJECT_DIR,
        env={**os.environ, "PYTHONUNBUFFERED": "1", **env}, preexec_fn=_die_with_parent if os.name == "posix" else None,
    )
    child = Child(name, proc, list(args), env)

    def drain() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            child._lines.put(line)
        child._lines.put(None)

    threading.Thread(target=drain, name=f"{name}-stdout", daemon=True).start()
    return child


def start_child(name: str, args: list[str], timeout: float) -> Child:
    """Run ``teleprog <args> --json`` and wait for the line saying where it listens."""
    return spawn_child(name, args).wait_ready(timeout)


def stop_child(child: Child, timeout: float = 10.0) -> None:
    proc = child.proc
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def spawn_robot_and_link(
    *, cell: Path, robot_port: int, link_port: int, delay_ms: float, credential: str, cache_dir: Path | None = None
) -> tuple[Child, Child, str]:
    """Start the telerobot and the link relaying to it at once, without waiting (the link reaches
    the robot only when a console joins, and ``teleprog up`` connects once both listen);
    returns both and the link's URL for the console. Ports 0 are chosen free here. The caller
    has loaded ``cell``: the robot listens before it loads it (``--listen-first``). ``cache_dir``:
    the robot's collision-model cache (None: none). ``credential``: what the robot will require of
    its consoles, handed to it in its environment (the link passes it through; it needs none)."""
    robot_port = robot_port or free_port()
    link_port = link_port or free_port()
    robot = spawn_child("telerobot", [
        "robot", "--port", str(robot_port), "--cell", str(cell), "--listen-first", "--cache-dir", str(cache_dir or "none"),
    ], env={ENV_VAR: credential})
    link = spawn_child(
        "link", ["link", "--port", str(link_port), "--robot", f"ws://127.0.0.1:{robot_port}", "--delay-ms", repr(float(delay_ms))]
    )
    return robot, link, f"ws://127.0.0.1:{link_port}"


class ChildWatch:
    """Watches started children on a thread: an exit is logged once, shown in ``status()``
    (``exited 1, restarting``) and, with ``restart``, the child is started again with the same
    arguments (its port is in them). ``children`` always lists the current processes."""

    def __init__(self, children: list[Child], *, restart: bool, start_timeout: float, poll_s: float = 0.2) -> None:
        self.children = list(children)
        self.restart = restart
        self.start_timeout = start_timeout
        self.poll_s = poll_s
        self._status = {c.name: "running" for c in children}
        self._restarts = {c.name: 0 for c in children}
        self._given_up: set[int] = set()  # ids of the Popen objects of exited children left exited (no restart)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="child-watch", daemon=True)

    def start(self) -> "ChildWatch":
        self._thread.start()
        return self

    def stop(self) -> list[Child]:
        """Stop watching (before the children are stopped on purpose); returns the current
        children, a restarting one included, for the caller to stop."""
        with self._lock:
            self._stop.set()
            children = list(self.children)
        self._thread.join(timeout=1.0)
        return children

    def status(self) -> dict[str, str]:
        with self._lock:
            return dict(self._status)

    def _set(self, name: str, text: str) -> None:
        with self._lock:
            self._status[name] = text

    def _run(self) -> None:
        while not self._stop.wait(self.poll_s):
            for i, child in enumerate(list(self.children)):
                if id(child.proc) in self._given_up:
                    continue
                code = child.proc.poll()  # reaps an exited child
                if code is not None and not self._stop.is_set():
                    self._exited(i, child, code)

    def _exited(self, i: int, child: Child, code: int) -> None:
        if not self.restart:
            log.warning("the %s exited with code %d; not restarting it (--no-restart)", child.name, code)
            self._set(child.name, f"exited {code}, not restarted")
            self._given_up.add(id(child.proc))
            return
        log.warning("the %s exited with code %d; starting it again", child.name, code)
        with self._lock:
            if self._stop.is_set():
                return
            self._status[child.name] = f"exited {code}, restarting"
            new = self.children[i] = spawn_child(child.name, child.args, child.env)
        try:
            new.wait_ready(self.start_timeout)
        except InputError as exc:  # it exited or never listened: the next poll tries again
            log.warning("restarting the %s failed: %s", child.name, exc)
            self._set(child.name, f"exited {code}, restart failed: {exc}")
            self._stop.wait(2.0)
            return
        with self._lock:
            self._restarts[child.name] += 1
            self._status[child.name] = f"running (restarted {self._restarts[child.name]}x; last exit {code})"
        log.info("the %s runs again at %s", child.name, new.url)
