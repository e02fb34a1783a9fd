"""What recording a session costs the console: its CPU with and without the MCAP recorder.

Both modes do a fixed piece of work, a drag of tool jogs (back and forth along x, 40 mm each way)
at the gizmo's full rate (100 Hz) while telemetry streams at 50 Hz, and compare the CPU time of
runs with and without the recorder (runs alternate; medians of each). Two figures each:

* **difference**: recorded minus unrecorded CPU, as a share of the unrecorded: everything the
  recorder costs, its threads' contention included, but noisy on a shared machine;
* **writer thread**: the CPU the recorder's writer thread spent (``WriterStats.cpu_s`` in
  process, ``/proc/PID/task/TID`` of the thread named ``teleprog-record`` in a console), as a
  share of the unrecorded run's CPU: the recorder's own work, steady, without its listeners on
  the console's threads (a few microseconds per event) and without contention.

**in process** (default): the console's ``Session`` alone in this process (no HTTP, no 3D scene,
no link), so the share it gives overstates the console's: 3,000 jogs with a telemetry frame handed
to it after every second jog, the session's clocks on the drag's simulated time (10 ms a jog), so
what is thinned by time (``/tf`` at 30 Hz per arm, the remote arm's events) is thinned as in a
real drag; the process's CPU (every thread, ``time.process_time``), the recorder's backlog and
closing included.

**processes** (``--processes``): a running ``teleprog up --delay-ms 200`` (the telerobot streams
telemetry at 50 Hz through the link to the console) while a client makes 1,500 tool jogs over
the HTTP API at 100 Hz (the path the page's gizmo takes: each an arm change, a collision check,
its events and the 3D scene's update), waiting for each answer. The console process's own CPU
(``/proc/PID/stat``, not its children) from the first jog until 0.3 s after the last (the
writer's backlog). Goal (issue 17): recording costs under 5 % of the console's CPU.

    .venv/bin/python benchmarks/bench_recording.py                # in process, table
    .venv/bin/python benchmarks/bench_recording.py --json
    .venv/bin/python benchmarks/bench_recording.py --processes    # running consoles
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

PROJECT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(PROJECT), str(PROJECT / "tests")]  # this checkout's code, not the installed one

from support import free_port, wait_for, wait_http  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int, tid: int | None = None) -> float:
    """User + system CPU of a process (or one of its threads), s."""
    path = f"/proc/{pid}/stat" if tid is None else f"/proc/{pid}/task/{tid}/stat"
    fields = Path(path).read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def writer_thread(pid: int) -> int | None:
    """The recorder's writer thread in console ``pid`` (named ``teleprog-record``)."""
    from server.recording.writer import OS_THREAD_NAME

    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            if Path(f"/proc/{pid}/task/{tid}/comm").read_text().strip() == OS_THREAD_NAME:
                return int(tid)
        except OSError:
            continue
    return None


def one_run(record: bool, jogs: int, rate_hz: float, folder: Path) -> dict:
    port = free_port()
    flags = ["--record", str(folder)] if record else ["--no-record"]
    proc = subprocess.Popen([sys.executable, "-m", "server.cli", "up", "--port", str(port), "--delay-ms", "200", *flags],
                            cwd=PROJECT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_http(url + "/api/health", proc, timeout=180)
        with httpx.Client(base_url=url, timeout=10) as client:
            wait_for(lambda: client.get("/api/link").json()["status"] == "live", 60, 0.1, "a live link")
            client.put("/api/program/auto", json={"on": False})  # the drag's own cost, not generation's
            time.sleep(2.0)  # telemetry flowing, start-up work done
            tid = writer_thread(proc.pid) if record else None
            w0 = cpu_s(proc.pid, tid) if tid else 0.0
            c0, t0 = cpu_s(proc.pid), time.perf_counter()
            period, next_at = 1.0 / rate_hz, time.perf_counter()
            for n in range(jogs):
                sign = 1.0 if (n // 40) % 2 == 0 else -1.0  # 40 mm one way, then back
                client.post("/api/jog/tool", json={"frame": "world", "constraint": "x", "motion": "translate",
                                                   "displacement": [sign * 1.0, 0.0, 0.0]})
                next_at += period
                time.sleep(max(0.0, next_at - time.perf_counter()))
            drag_s = time.perf_counter() - t0
            time.sleep(0.3)  # the writer's backlog (it writes every 20 ms)
            c1, t1 = cpu_s(proc.pid), time.perf_counter()
            w1 = cpu_s(proc.pid, tid) if tid else 0.0
            rec = client.get("/api/sessions").json()["recording"]
    finally:
        proc.terminate()
        proc.wait(30)
    return {"recorded": record, "cpu_s": c1 - c0, "writer_cpu_s": w1 - w0, "wall_s": t1 - t0, "jogs": jogs,
            "jogs_per_s": jogs / drag_s, "written": rec["written"] if rec else 0, "dropped": rec["dropped"] if rec else 0}


def in_process_run(record: bool, jogs: int, folder: Path, rate_hz: float = 100.0) -> dict:
    import numpy as np

    from server.console import Session
    from server.recording.recorder import SessionRecorder
    from shared.cells.loader import DEFAULT_CELL, load_cell
    from shared.wire.messages import ControlMode, RobotState
    from shared.wire.telemetry import TelemetryFrame

    cell = load_cell(DEFAULT_CELL)
    start = time.time()
    simulated = [0.0]  # the session's clocks run on the drag's time: a jog every 1 / rate_hz
    session = Session(cell, clock=lambda: 1e6 + simulated[0], wall_clock=lambda: start + simulated[0])
    session.program.set_auto_generate(False)
    q0 = session.arm.state.q.copy()
    recorder = SessionRecorder(session, folder / f"bench-{time.time_ns()}.mcap", cell_file=DEFAULT_CELL) if record else None
    if recorder is not None:
        recorder.start()
    c0 = time.process_time()
    for i in range(jogs):
        simulated[0] = (i + 1) / rate_hz
        sign = 1.0 if (i // 40) % 2 == 0 else -1.0
        session.arm.jog_tool(frame="world", constraint="x", motion="translate", displacement=np.array([sign * 1e-3, 0.0, 0.0]))
        if i % 2 == 0:
            q = q0 + 1e-4 * (i % 80)
            session.remote.on_telemetry(TelemetryFrame(
                time=i * 0.02, frame=i // 2, state=RobotState.RUNNING, mode=ControlMode.POSITION, statement=1,
                q=tuple(q.tolist()), position=(0.4, 0.1, 0.3), rpy=(0.0, 0.0, 0.0)))
    written = dropped = 0
    writer_cpu = 0.0
    if recorder is not None:
        stats = recorder.close()
        written, dropped, writer_cpu = stats.written, stats.dropped, getattr(stats, "cpu_s", 0.0)  # 0: a writer before it
    return {"recorded": record, "cpu_s": time.process_time() - c0, "writer_cpu_s": writer_cpu, "jogs": jogs,
            "written": written, "dropped": dropped}


def summary(runs: list[dict]) -> dict:
    on = statistics.median(r["cpu_s"] for r in runs if r["recorded"])
    off = statistics.median(r["cpu_s"] for r in runs if not r["recorded"])
    writer = statistics.median(r["writer_cpu_s"] for r in runs if r["recorded"])
    return {"cpu_s_recorded": on, "cpu_s_unrecorded": off, "writer_cpu_s": writer,
            "difference_pct": 100 * (on - off) / off, "writer_pct": 100 * writer / off, "goal_pct": 5.0,
            "written": statistics.median(r["written"] for r in runs if r["recorded"]),
            "dropped": max(r["dropped"] for r in runs if r["recorded"])}


def table(result: dict, jogs: int, what: str) -> None:
    on, off = result["cpu_s_recorded"], result["cpu_s_unrecorded"]
    print(f"| {what}, unrecorded | {off:.2f} s CPU ({1e3 * off / jogs:.2f} ms per jog) |")
    print(f"| {what}, recorded | {on:.2f} s CPU ({1e3 * on / jogs:.2f} ms per jog) |")
    print(f"| recording's cost: difference | {result['difference_pct']:+.1f} % (goal < 5 %) |")
    print(f"| recording's cost: writer thread | {result['writer_cpu_s']:.2f} s CPU, {result['writer_pct']:.1f} % "
          f"({1e6 * result['writer_cpu_s'] / jogs:.0f} us per jog) |")
    print(f"| messages written per run | {result['written']:.0f}, dropped {result['dropped']} |")


def run_pairs(args: argparse.Namespace, one) -> list[dict]:
    runs = []
    for i in range(args.pairs):
        for record in (i % 2 == 0, i % 2 != 0):  # alternate which goes first
            runs.append(one(record))
            r = runs[-1]
            print(f"run {len(runs)}: {'recorded' if record else 'unrecorded'} {r['cpu_s']:.2f} s CPU, "
                  f"writer {r['writer_cpu_s']:.2f} s", file=sys.stderr)
    return runs


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=100.0, help="jogs per second (the gizmo's full rate)")
    parser.add_argument("--pairs", type=int, default=3, help="recorded/unrecorded run pairs")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--processes", action="store_true", help="measure running teleprog up processes instead")
    parser.add_argument("--jogs", type=int, default=None, help="jogs per run (default 3000 in process, 1500 in processes)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.processes:
            jogs = args.jogs or 1500
            runs = run_pairs(args, lambda record: one_run(record, jogs, args.rate, Path(tmp)))
        else:
            jogs = args.jogs or 3000
            in_process_run(True, 200, Path(tmp), args.rate)  # warm-up: imports, caches, numba
            runs = run_pairs(args, lambda record: in_process_run(record, jogs, Path(tmp), args.rate))
    result = {"mode": "processes" if args.processes else "in process", "jogs": jogs, "runs": runs, **summary(runs)}
    if args.processes:
        result["jogs_per_s"] = statistics.median(r["jogs_per_s"] for r in runs)
    if args.json:
        print(json.dumps(result))
    else:
        table(result, jogs, "console process" if args.processes else "session work")
        if args.processes:
            print(f"| drag rate reached | {result['jogs_per_s']:.0f} jogs/s (asked {args.rate:.0f}) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
