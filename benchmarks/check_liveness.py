"""Does the console's own work ever starve the robot's link? (issue 35)

A real ``teleprog up`` (telerobot, 300 ms link, console on free ports, ``--fault-injection``) runs
a slow drive on the robot while the console is made to work hard, one load after another:

1. ``stall``: ``POST /api/faults/stall`` holds the session for 5 s (a plan computing);
2. ``load``: ``POST /api/program/upload`` of a ``--lines``-line program (default 20,000);
3. ``preview start``: a preview of the first ``--submit`` statements begun (the answer; the task
   panel's play of the range follows on its own thread), then ended;
4. ``submit``: the first ``--submit`` statements of a program submitted at once (default 1,000).

Throughout, the telerobot's ``/health`` is polled every 50 ms (no delay: it is the robot's own
port) and the console's ``/api/health`` is timed. Reported per load: its wall time, whether the
robot halted (and why), the robot's state, and the console's ``/api/health`` answer times
(median, p99, max). The robot halts for silence when no console message reaches it for its
silence limit (1 s): any halt here is a failure of the console's liveness.

    .venv/bin/python benchmarks/check_liveness.py            # about 2-3 min on 2 cores
    .venv/bin/python benchmarks/check_liveness.py --json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]
CLIENT = {"X-Teleprog-Client": "liveness-check"}


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Console:
    def __init__(self, log_dir: Path, delay_ms: float) -> None:
        self.port = _free_port()
        self.log_path = log_dir / "console.log"
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "server.cli", "up", "--delay-ms", str(delay_ms), "--fault-injection", "--no-record",
             "--port", str(self.port)],
            stdout=self.log_path.open("w"), stderr=subprocess.STDOUT, cwd=ROOT, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        self.http = httpx.Client(base_url=f"http://127.0.0.1:{self.port}", headers=CLIENT, timeout=600)
        self._wait(lambda: self.http.get("/api/health").status_code == 200, 180, "the console")
        m = self._wait(lambda: re.search(r"telerobot ws://127\.0\.0\.1:(\d+)", self.log_path.read_text()), 60, "the robot's port")
        self.robot = httpx.Client(base_url=f"http://127.0.0.1:{m[1]}", timeout=5)
        self._wait(lambda: self.api("GET", "/api/link")["status"] == "live", 60, "a live link")

    @staticmethod
    def _wait(predicate, timeout: float, what: str):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                if value := predicate():
                    return value
            except httpx.HTTPError:
                pass
            time.sleep(0.1)
        raise SystemExit(f"check_liveness: {what} not up within {timeout:g} s")

    def api(self, method: str, path: str, **kw) -> dict:
        r = self.http.request(method, path, **kw)
        if r.status_code != 200:
            raise SystemExit(f"check_liveness: {method} {path}: {r.status_code} {r.text[:300]}")
        return r.json()

    def close(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def _start_drive(c: Console) -> None:
    """A drive slow enough to outlast every load, running on the robot."""
    c.api("POST", "/api/robot/abort")
    c.api("PUT", "/api/regime", json={"regime": "free"})
    c.api("POST", "/api/program/load", json={"text": "", "filename": "empty.tp"})
    q = c.api("GET", "/api/arm")["q_deg"]
    for text in ("SPEED 1 %", f"DRIVE J1 TO {q[0] + 60:.2f} deg", f"DRIVE J1 TO {q[0]:.2f} deg"):
        c.api("POST", "/api/program/insert", json={"text": text})
    c.api("POST", "/api/submit", json={"start": 0, "stop": 3})
    Console._wait(lambda: c.robot.get("/health").json()["state"] == "running", 30, "the drive running")


def stop_in_stall(c: Console, stall_s: float) -> dict:
    """STOP pressed while the session stalls, with a drive running: when the robot stops (its own
    ``/health``) and when the console shows the STOP acknowledged (``/api/link``'s
    ``recovery_pending`` empty), both from the press, each polled every 5 ms on a thread of its own."""
    _start_drive(c)
    c.api("POST", "/api/faults/stall", json={"seconds": stall_s})
    time.sleep(0.5)  # well inside the stall
    times: dict = {"robot_stopped_s": None, "acknowledged_s": None}
    t0 = time.perf_counter()

    def robot_stopped() -> bool:
        return c.robot.get("/health").json()["state"] == "stopped"

    def acknowledged() -> bool:
        pending = httpx.get(f"http://127.0.0.1:{c.port}/api/link", headers=CLIENT, timeout=60).json()["recovery_pending"]
        seen.append(bool(pending))
        return any(seen) and not pending

    seen: list[bool] = []

    def poll(key: str, done) -> None:
        while time.perf_counter() - t0 < stall_s + 10:
            if done():
                times[key] = time.perf_counter() - t0
                return
            time.sleep(0.005)

    pollers = [threading.Thread(target=poll, args=("robot_stopped_s", robot_stopped)),
               threading.Thread(target=poll, args=("acknowledged_s", acknowledged))]
    for t in pollers:
        t.start()
    httpx.post(f"http://127.0.0.1:{c.port}/api/robot/stop", headers=CLIENT, timeout=60)
    for t in pollers:
        t.join()
    time.sleep(max(0.0, stall_s - (time.perf_counter() - t0)))
    return times


def _program(lines: int) -> str:
    """``lines`` small joint moves back and forth (each a valid statement)."""
    return "\n".join(f"DRIVE J1 TO {(-1) ** i * 0.5:.1f} deg" for i in range(lines)) + "\n"


def watch(c: Console, work) -> dict:
    """Run ``work()`` while polling the robot and timing the console's health answer."""
    answers, states, halted = [], set(), None
    done = threading.Event()
    result: dict = {}

    def run() -> None:
        t0 = time.perf_counter()
        try:
            result["detail"] = work()
        except BaseException as exc:  # noqa: BLE001 - reported
            result["error"] = str(exc)
        result["wall_s"] = time.perf_counter() - t0
        done.set()

    threading.Thread(target=run, daemon=True).start()
    while not done.is_set():
        h = c.robot.get("/health").json()
        states.add(h["state"])
        if h["halted"] and halted is None:
            halted = h["halted"]
        t = time.perf_counter()
        try:
            c.http.get("/api/health", timeout=30)
            answers.append(time.perf_counter() - t)
        except httpx.HTTPError:
            answers.append(float("inf"))
        time.sleep(0.05)
    answers.sort()
    return {**result, "robot_halted": halted, "robot_states": sorted(states),
            "console_health_ms": {"median": 1e3 * statistics.median(answers) if answers else None,
                                  "p99": 1e3 * answers[min(len(answers) - 1, int(0.99 * len(answers)))] if answers else None,
                                  "max": 1e3 * answers[-1] if answers else None, "n": len(answers)}}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--lines", type=int, default=20_000)
    p.add_argument("--submit", type=int, default=1_000)
    p.add_argument("--stall-s", type=float, default=5.0)
    p.add_argument("--delay-ms", type=float, default=300.0)
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    out: dict = {"lines": a.lines, "submit": a.submit, "delay_ms": a.delay_ms, "load_before": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory() as d:
        c = Console(Path(d), a.delay_ms)
        try:
            _start_drive(c)
            out["stall"] = watch(c, lambda: (c.api("POST", "/api/faults/stall", json={"seconds": a.stall_s}),
                                             time.sleep(a.stall_s + 0.5))[0])
            out["stop_in_stall"] = stop_in_stall(c, a.stall_s)
            text = _program(a.lines)
            out["load"] = watch(c, lambda: len(c.api("POST", "/api/program/upload", params={"filename": "long.tp"},
                                                     content=text.encode(), headers={"content-type": "text/plain"})["entries"]) - 1)
            c.api("POST", "/api/robot/abort")
            _start_drive(c)
            c.api("POST", "/api/program/upload", params={"filename": "long.tp"}, content=_program(a.submit).encode(),
                  headers={"content-type": "text/plain"})
            out["preview_start"] = watch(c, lambda: c.api("POST", "/api/preview/begin", json={"start": 0, "stop": a.submit})["stop"])
            c.api("POST", "/api/preview/end")
            out["submit_run"] = watch(c, lambda: len(c.api("POST", "/api/submit", json={"start": 0, "stop": a.submit})["items"]))
        finally:
            c.close()
    out["load_after"] = os.getloadavg()[0]
    if a.json:
        print(json.dumps(out, indent=2))
        return
    print(f"| load ({a.delay_ms:g} ms link, machine load {out['load_before']:.1f} -> {out['load_after']:.1f}) | wall | robot halted | "
          "robot states | console /api/health median / p99 / max |")
    print("|---|---:|---|---|---:|")
    names = {"stall": f"session stalled {a.stall_s:g} s", "load": f"upload of {a.lines:,} lines",
             "preview_start": f"preview start of {a.submit:,} statements", "submit_run": f"submit of {a.submit:,} statements"}
    st = out["stop_in_stall"]
    fmt = lambda v: "never" if v is None else f"{v:.2f} s"  # noqa: E731
    print(f"\nSTOP pressed during a {a.stall_s:g} s stall ({a.delay_ms:g} ms each way): the robot stopped after "
          f"{fmt(st['robot_stopped_s'])}, the console showed it acknowledged after {fmt(st['acknowledged_s'])} "
          f"(goal: the round trip, {2 * a.delay_ms / 1e3:.1f} s, plus 0.2 s)\n")
    for key, name in names.items():
        r = out[key]
        h = r["console_health_ms"]
        err = f" (error: {r['error'][:80]})" if r.get("error") else ""
        print(f"| {name}{err} | {r['wall_s']:.2f} s | {r['robot_halted'] or 'no'} | {', '.join(r['robot_states'])} | "
              f"{h['median']:.0f} / {h['p99']:.0f} / {h['max']:.0f} ms |")


if __name__ == "__main__":
    main()
