"""The console's CPU per telemetry frame, with no page open (issue 35).

What is measured, exactly:

* Two real processes on loopback, free ports, the default cell: a telerobot
  (``teleprog robot --port P``) and a console attached straight to it
  (``teleprog up --port Q --robot-url ws://127.0.0.1:P --no-record``: no link process, no
  recording, no browser page, nobody on ``/api/events``). The console's receive path is the one
  it uses through a link: ``RobotClient`` on the ``robot-io`` thread, its delivery thread, the
  session's remote mirror, the event bus and whatever the 3D page's code listens with. With
  ``--record`` the consoles record the session as ``teleprog up`` does by default (the recorder
  writes every telemetry frame).
* Two modes, the only difference being the telerobot's frame rate (``TELEPROG_ROBOT_TELEMETRY_RATE``,
  the robot's own setting): ``stream`` at the protocol's 50 Hz and ``low`` at ``--low-rate``
  (default 2 Hz, slow enough to cost nothing much, fast enough that the console never calls
  the telemetry stale). Heartbeats, the session's clock, the link view's timer and everything
  else the console does run alike in both.
* For each mode in each round, a fresh robot and console are started and waited for by states
  (robot ``/health`` says ``core_ready``; console ``/api/health`` answers; ``/api/link`` says the
  command channel and the telemetry are ``live``; ``/api/remote`` shows the robot's arm), then
  ``--warmup`` seconds pass and the console process's CPU time (user + system, all threads,
  ``/proc/PID/stat``, in 10 ms ticks: about 0.5 ms/s of resolution over 20 s) is read over
  ``--seconds`` of wall time. Modes alternate within a round and their order alternates between
  rounds; the headline figures are medians over rounds, each round's own figure is listed too.
* Frames received: from the console's own count (``/api/link`` ``telemetry_frames``) read at
  the window's two ends when the console reports it; otherwise estimated as rate x wall time
  (marked ``estimated``).
* **ms CPU per frame** = (CPU ms per s in ``stream`` - CPU ms per s in ``low``) / (frames per s
  in ``stream`` - frames per s in ``low``). The ``low`` mode's own frames are thereby priced at
  the same per-frame cost, so its fixed costs drop out.
* Per thread: the same window's CPU of each of the console's threads (``/proc/PID/task/TID/stat``),
  named from one ``py-spy dump`` taken before the window (``robot-io``: the robot client's loop;
  ``robot-listeners``: its delivery thread; ``MainThread``: uvicorn, the API, viser;
  ``session-clock``: the session's 20 Hz tick).
* With ``--profile S`` (default 20 s; 0: none), after the CPU window of the last round, py-spy
  samples the console for S seconds in each mode (``py-spy record -f raw --nonblocking --gil -t``,
  ``--profile-rate`` Hz, default 1000: only the thread holding the interpreter lock, so time a
  thread waits in epoll or on a lock is not counted, nor is time spent in the kernel); the
  summary gives, per function (leaf = self, and inclusive) and per thread, CPU ms per second in
  each mode and the difference per frame in us. The sampler runs outside the CPU window, so it
  does not inflate the headline figure, but it shares the two cores with the console meanwhile.

Run from the repository root::

    .venv/bin/python benchmarks/bench_telemetry_cost.py                 # tables and profile, ~4 min
    .venv/bin/python benchmarks/bench_telemetry_cost.py --seconds 20 --rounds 3 --profile 0 --json
    .venv/bin/python benchmarks/bench_telemetry_cost.py --record        # consoles that record
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import secrets
import re
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]
CLIENT = {"X-Teleprog-Client": "bench-telemetry"}
STREAM_RATE_HZ = 50.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds the process has used, all its threads (Linux ``/proc``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _tail(*logs: Path) -> str:
    return "".join(f"\n--- {log.name} ---\n{log.read_text()[-2000:]}" for log in logs if log.exists())


def _wait(predicate, timeout: float, what: str, proc: subprocess.Popen, *logs: Path):
    """Poll ``predicate`` (every 0.1 s) until it returns something truthy; HTTP errors count as
    not yet. Fails, with the logs' ends, when ``proc`` exits first or ``timeout`` passes."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise SystemExit(f"bench_telemetry_cost: the process for {what} exited with {proc.returncode}{_tail(*logs)}")
        try:
            if value := predicate():
                return value
        except (httpx.HTTPError, ValueError, KeyError):
            pass
        time.sleep(0.1)
    raise SystemExit(f"bench_telemetry_cost: {what} not reached within {timeout:g} s{_tail(*logs)}")


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


class Pair:
    """A telerobot at ``rate`` Hz and a console attached to it, both started and ready."""

    def __init__(self, rate: float, log_dir: Path, tag: str, record: bool = False) -> None:
        # the robot and its console share a credential (shared.wire.credential), as teleprog up's do
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "TELEPROG_ROBOT_TELEMETRY_RATE": repr(float(rate)),
               "TELEPROG_ROBOT_CREDENTIAL": os.environ.get("TELEPROG_ROBOT_CREDENTIAL") or secrets.token_urlsafe(32)}
        self.rate = rate
        self.robot_port, self.port = _free_port(), _free_port()
        self.robot_log, self.console_log = log_dir / f"robot-{tag}.log", log_dir / f"console-{tag}.log"
        self.robot = subprocess.Popen(
            [sys.executable, "-m", "server.cli", "robot", "--port", str(self.robot_port)],
            stdout=self.robot_log.open("w"), stderr=subprocess.STDOUT, cwd=ROOT, env=env)
        self.console: subprocess.Popen | None = None
        self.http = httpx.Client(base_url=f"http://127.0.0.1:{self.port}", headers=CLIENT, timeout=30)
        try:
            _wait(lambda: httpx.get(f"http://127.0.0.1:{self.robot_port}/health", timeout=2).json()["core_ready"],
                  180, "the telerobot's core", self.robot, self.robot_log)
            logs = (self.console_log, self.robot_log)
            self.console = subprocess.Popen(
                [sys.executable, "-m", "server.cli", "up", "--port", str(self.port),
                 "--robot-url", f"ws://127.0.0.1:{self.robot_port}",
                 *(["--record", str(log_dir / f"recordings-{tag}")] if record else ["--no-record"])],
                stdout=self.console_log.open("w"), stderr=subprocess.STDOUT, cwd=ROOT, env=env)
            _wait(lambda: self.http.get("/api/health").status_code == 200, 180, "the console's /api/health",
                  self.console, *logs)
            _wait(lambda: (v := self.link())["status"] == "live" and v["telemetry"] == "live", 60,
                  "a live command channel and telemetry", self.console, *logs)
            _wait(lambda: self.http.get("/api/remote").status_code == 200, 60, "the remote arm shown", self.console, *logs)
        except BaseException:
            self.close()
            raise

    @property
    def pid(self) -> int:
        assert self.console is not None
        return self.console.pid

    def link(self) -> dict:
        r = self.http.get("/api/link")
        r.raise_for_status()
        return r.json()

    def frames(self) -> int | None:
        """Frames the console has received (None: this console does not report them)."""
        value = self.link().get("telemetry_frames")
        return None if value is None else int(value)

    def close(self) -> None:
        if self.console is not None:
            _stop(self.console)
        _stop(self.robot)
        self.http.close()


def _thread_cpu_s(pid: int) -> dict[int, float]:
    """CPU seconds of each of the process's threads, by thread id."""
    out = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except FileNotFoundError:  # the thread ended meanwhile
            continue
        out[int(task.name)] = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return out


def _thread_names(pid: int) -> dict[int, str]:
    """Python's names of the process's threads by thread id (one ``py-spy dump``; empty without py-spy)."""
    exe = _py_spy()
    if exe is None:
        return {}
    dump = subprocess.run([exe, "dump", "-p", str(pid), "--nonblocking"], capture_output=True, text=True).stdout
    return {int(m[1]): _thread_label(m[2]) for m in re.finditer(r'Thread (\d+) \([^)]*\): "([^"]*)"', dump)}


def _thread_label(name: str) -> str:
    """A thread's name without what differs between runs (a port, a counter, a recording's file)."""
    name = re.sub(r"session-\S+\.mcap", "(file)", name)
    return re.sub(r"ws://[^ ]+", "ws://...", re.sub(r"-\d+( |$)", r"\1", name))


def measure(pair: Pair, seconds: float) -> dict:
    """The console's CPU over ``seconds`` of wall time (in all and per thread), and the frames it
    received meanwhile."""
    names = _thread_names(pair.pid)
    f0 = pair.frames()
    t0, c0, th0 = time.perf_counter(), _cpu_s(pair.pid), _thread_cpu_s(pair.pid)
    time.sleep(seconds)
    c1, th1, t1 = _cpu_s(pair.pid), _thread_cpu_s(pair.pid), time.perf_counter()
    f1 = pair.frames()
    wall = t1 - t0
    counted = f0 is not None and f1 is not None
    frames = (f1 - f0) if counted else pair.rate * wall
    link = pair.link()
    threads: collections.Counter[str] = collections.Counter()
    for tid, cpu in th1.items():
        threads[names.get(tid, "other")] += 1e3 * (cpu - th0.get(tid, 0.0)) / wall
    return {"wall_s": wall, "cpu_s": c1 - c0, "cpu_ms_per_s": 1e3 * (c1 - c0) / wall, "frames": frames,
            "frames_per_s": frames / wall, "frames_counted": counted, "telemetry": link["telemetry"],
            "errors": link.get("errors", 0), "threads_ms_per_s": dict(threads)}


# -- the profile ---------------------------------------------------------------------------------
def _py_spy() -> str | None:
    here = Path(sys.executable).with_name("py-spy")
    return str(here) if here.exists() else shutil.which("py-spy")


def profile(pid: int, seconds: int, rate_hz: int, out: Path) -> dict | None:
    """py-spy raw stacks of the console for ``seconds``: samples per (thread, stack)."""
    exe = _py_spy()
    if exe is None:
        return None
    subprocess.run([exe, "record", "-p", str(pid), "-d", str(seconds), "-r", str(rate_hz), "-f", "raw", "-t", "-F",
                    "--gil", "--nonblocking", "-o", str(out)], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    stacks: collections.Counter[str] = collections.Counter()
    for line in out.read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        if stack and count.isdigit():
            stacks[stack] += int(count)
    return {"seconds": seconds, "rate_hz": rate_hz, "stacks": stacks}


def _frame_name(part: str) -> str:
    """``function (path/file.py:12)`` -> ``function (file.py)``."""
    name, _, where = part.partition(" (")
    where = where.rstrip(")").rsplit(":", 1)[0]
    return f"{name} ({where.rsplit('/', 1)[-1]})" if where else name


def summarise(prof: dict) -> dict:
    """Samples per second by thread, by leaf function (self) and by function (inclusive)."""
    by_thread: collections.Counter[str] = collections.Counter()
    leaf: collections.Counter[str] = collections.Counter()
    incl: collections.Counter[str] = collections.Counter()
    total = 0
    for stack, n in prof["stacks"].items():
        parts = stack.split(";")
        thread = next((p for p in parts[:2] if p.startswith("thread")), "thread ?")
        thread = _thread_label(re.sub(r"^thread \(0?x?[0-9a-f]+\)[: ]*", "", thread)) or "thread ?"
        frames = [_frame_name(p) for p in parts if not p.startswith(("thread", "process"))]
        if not frames:
            continue
        total += n
        by_thread[thread] += n
        leaf[frames[-1]] += n
        for name in set(frames):
            incl[name] += n
    per_s = prof["rate_hz"] * prof["seconds"] / 1e3  # samples per CPU ms of one second of wall time
    scale = lambda c: {k: v / per_s for k, v in c.items()}  # noqa: E731 - samples -> CPU ms per s
    return {"total": total / per_s, "thread": scale(by_thread), "self": scale(leaf), "inclusive": scale(incl)}


def profile_table(stream: dict, low: dict, fps_diff: float, top: int) -> dict:
    """Per function: CPU ms per s in each mode and the difference per frame in us."""
    out = {}
    for kind in ("self", "inclusive", "thread"):
        names = set(stream[kind]) | set(low[kind])
        rows = [(n, stream[kind].get(n, 0.0), low[kind].get(n, 0.0)) for n in names]
        rows.sort(key=lambda r: r[1] - r[2], reverse=True)
        out[kind] = [{"name": n, "stream_ms_per_s": s, "low_ms_per_s": lo, "us_per_frame": 1e3 * (s - lo) / fps_diff}
                     for n, s, lo in rows[:top]]
    out["total"] = {"stream_ms_per_s": stream["total"], "low_ms_per_s": low["total"],
                    "us_per_frame": 1e3 * (stream["total"] - low["total"]) / fps_diff}
    return out


# -- main -------------------------------------------------------------------------------------------
def run(args: argparse.Namespace) -> dict:
    out: dict = {"record": args.record, "seconds": args.seconds, "warmup_s": args.warmup, "rounds": args.rounds, "low_rate_hz": args.low_rate,
                 "stream_rate_hz": STREAM_RATE_HZ, "load_before": os.getloadavg(),
                 "date_utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()), "runs": {"stream": [], "low": []},
                 "root": str(ROOT)}
    profiles: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="bench-telemetry-") as d:
        for r in range(args.rounds):
            order = ("stream", "low") if r % 2 == 0 else ("low", "stream")
            for mode in order:
                rate = STREAM_RATE_HZ if mode == "stream" else args.low_rate
                pair = Pair(rate, Path(d), f"{mode}-{r}", record=args.record)
                try:
                    time.sleep(args.warmup)
                    m = measure(pair, args.seconds)
                    out["runs"][mode].append(m)
                    if not args.json:
                        print(f"round {r + 1} {mode:6s}: {m['cpu_ms_per_s']:6.1f} ms CPU/s, {m['frames_per_s']:5.1f} frames/s"
                              f"{'' if m['frames_counted'] else ' (estimated)'}", file=sys.stderr, flush=True)
                    if args.profile and r == args.rounds - 1:
                        prof = profile(pair.pid, args.profile, args.profile_rate, Path(d) / f"{mode}.raw")
                        if prof is not None:
                            profiles[mode] = summarise(prof)
                finally:
                    pair.close()
    med = {mode: {"cpu_ms_per_s": statistics.median(m["cpu_ms_per_s"] for m in runs),
                  "frames_per_s": statistics.median(m["frames_per_s"] for m in runs)}
           for mode, runs in out["runs"].items()}
    fps_diff = med["stream"]["frames_per_s"] - med["low"]["frames_per_s"]
    out["median"] = med
    for mode, runs in out["runs"].items():
        names = sorted({n for m in runs for n in m["threads_ms_per_s"]})
        med[mode]["threads_ms_per_s"] = {n: statistics.median(m["threads_ms_per_s"].get(n, 0.0) for m in runs) for n in names}
    out["frames_counted"] = all(m["frames_counted"] for runs in out["runs"].values() for m in runs)
    out["ms_cpu_per_frame"] = (med["stream"]["cpu_ms_per_s"] - med["low"]["cpu_ms_per_s"]) / fps_diff
    # per round as well, pairing each round's two modes (shows the spread the median hides)
    out["ms_cpu_per_frame_rounds"] = [
        (s["cpu_ms_per_s"] - lo["cpu_ms_per_s"]) / (s["frames_per_s"] - lo["frames_per_s"])
        for s, lo in zip(out["runs"]["stream"], out["runs"]["low"])]
    if "stream" in profiles and "low" in profiles:
        out["profile"] = profile_table(profiles["stream"], profiles["low"], fps_diff, args.top)
        out["profile"]["seconds"] = args.profile
    out["load_after"] = os.getloadavg()
    return out


def print_table(out: dict) -> None:
    med = out["median"]
    load = f"{out['load_before'][0]:.2f} -> {out['load_after'][0]:.2f}"
    print(f"\n{out['date_utc']} UTC, {out['rounds']} rounds of {out['seconds']:g} s per mode, load average (1 min) {load}\n")
    print("| mode | console CPU (median) | frames received | per round |")
    print("|---|---:|---:|---|")
    for mode, rate in (("stream", out["stream_rate_hz"]), ("low", out["low_rate_hz"])):
        rounds = ", ".join(f"{m['cpu_ms_per_s']:.1f}" for m in out["runs"][mode])
        note = "" if out["frames_counted"] else " (estimated)"
        print(f"| robot at {rate:g} Hz | {med[mode]['cpu_ms_per_s']:.1f} ms/s | {med[mode]['frames_per_s']:.1f}/s{note} | {rounds} ms/s |")
    rounds = ", ".join(f"{v:.3f}" for v in out["ms_cpu_per_frame_rounds"])
    print(f"| **CPU per frame** | **{out['ms_cpu_per_frame']:.3f} ms** | | {rounds} ms |")
    fps_diff = med["stream"]["frames_per_s"] - med["low"]["frames_per_s"]
    names = sorted(set(med["stream"]["threads_ms_per_s"]) | set(med["low"]["threads_ms_per_s"]),
                   key=lambda n: -med["stream"]["threads_ms_per_s"].get(n, 0.0))
    print("\n| thread (CPU, medians) | 50 Hz ms/s | low ms/s | ms per frame |")
    print("|---|---:|---:|---:|")
    for n in names:
        s, lo = med["stream"]["threads_ms_per_s"].get(n, 0.0), med["low"]["threads_ms_per_s"].get(n, 0.0)
        print(f"| {n} | {s:.1f} | {lo:.1f} | {(s - lo) / fps_diff:.3f} |")
    prof = out.get("profile")
    if not prof:
        return
    t = prof["total"]
    print(f"\nProfile (py-spy --gil, {prof['seconds']:g} s per mode): {t['stream_ms_per_s']:.1f} ms/s at 50 Hz, "
          f"{t['low_ms_per_s']:.1f} ms/s at {out['low_rate_hz']:g} Hz, {t['us_per_frame']:.0f} us a frame\n")
    for kind, title in (("thread", "thread"), ("self", "function (self)"), ("inclusive", "function (inclusive)")):
        print(f"| {title} | 50 Hz ms/s | low ms/s | us per frame |")
        print("|---|---:|---:|---:|")
        for row in prof[kind]:
            print(f"| {row['name']} | {row['stream_ms_per_s']:.1f} | {row['low_ms_per_s']:.1f} | {row['us_per_frame']:.1f} |")
        print()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=20.0, help="CPU window per mode and round (s)")
    p.add_argument("--warmup", type=float, default=3.0, help="seconds after readiness before the window")
    p.add_argument("--rounds", type=int, default=3, help="rounds; each starts both modes afresh")
    p.add_argument("--low-rate", type=float, default=2.0, help="the low mode's telemetry rate (Hz)")
    p.add_argument("--profile", type=int, default=20, help="py-spy seconds per mode in the last round (0: none)")
    p.add_argument("--profile-rate", type=int, default=1000, help="py-spy samples per second")
    p.add_argument("--top", type=int, default=25, help="rows per profile table")
    p.add_argument("--record", action="store_true", help="consoles record the session (the default of teleprog up); "
                   "without it, --no-record")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = p.parse_args()
    out = run(args)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print_table(out)


if __name__ == "__main__":
    main()
