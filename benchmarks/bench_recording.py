"""What recording a session costs the console: its CPU with and without the MCAP recorder.

**in process** (the figure): the console's session in this process does a fixed piece of work,
a drag of 3,000 tool jogs (back and forth along x, 40 mm each way) with a telemetry frame handed
to it after every second jog (the 50 Hz stream under a 100 Hz drag), then closes the recorder
(its writer's backlog counts). The process's CPU time (every thread: ``time.process_time``) with
and without a ``SessionRecorder``; runs alternate, medians of each. Fixed work, no sleeps: the
figure does not depend on how busy the machine is.

**processes** (``--processes``): a running ``teleprog up --delay-ms 200`` (telerobot streaming telemetry at 50 Hz through the
link, the console receiving it) while a client drags the virtual arm at the gizmo's full rate
(one tool jog every 10 ms, back and forth along x, over the HTTP API: the same session path the
page's gizmo takes, each move an arm change, a collision check and its events). The console
process's own CPU time (``/proc/PID/stat`` user + system, not its children) is read over a fixed
window; runs alternate recorded (``--record DIR``) and unrecorded (``--no-record``), and the
figure is the median of each. Goal (issue 17): recording costs under 5 % of the console's CPU.

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
import threading
import time
from pathlib import Path

import httpx

PROJECT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(PROJECT), str(PROJECT / "tests")]  # this checkout's code, not the installed one

from support import free_port, wait_for, wait_http  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def one_run(record: bool, seconds: float, rate_hz: float, folder: Path) -> dict:
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
            stop = threading.Event()
            moves = [0]

            def drag() -> None:
                period, step, n = 1.0 / rate_hz, 1.0, 0
                next_at = time.perf_counter()
                while not stop.is_set():
                    sign = 1.0 if (n // 40) % 2 == 0 else -1.0  # 40 mm one way, then back
                    client.post("/api/jog/tool", json={"frame": "world", "constraint": "x", "motion": "translate",
                                                       "displacement": [sign * step, 0.0, 0.0]})
                    n += 1
                    next_at += period
                    time.sleep(max(0.0, next_at - time.perf_counter()))
                moves[0] = n

            worker = threading.Thread(target=drag, daemon=True)
            c0, t0 = cpu_s(proc.pid), time.perf_counter()
            worker.start()
            time.sleep(seconds)
            stop.set()
            worker.join(10)
            c1, t1 = cpu_s(proc.pid), time.perf_counter()
            rec = client.get("/api/sessions").json()["recording"]
    finally:
        proc.terminate()
        proc.wait(30)
    return {"recorded": record, "cpu_s": c1 - c0, "wall_s": t1 - t0, "cpu_pct": 100.0 * (c1 - c0) / (t1 - t0),
            "moves": moves[0], "written": rec["written"] if rec else 0, "dropped": rec["dropped"] if rec else 0}


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
    if recorder is not None:
        stats = recorder.close()
        written, dropped = stats.written, stats.dropped
    return {"recorded": record, "cpu_s": time.process_time() - c0, "jogs": jogs, "written": written, "dropped": dropped}


def main_in_process(args: argparse.Namespace) -> int:
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        in_process_run(True, 200, Path(tmp))  # warm-up: imports, caches, numba
        for i in range(args.pairs):
            for record in (i % 2 == 0, i % 2 != 0):
                runs.append(in_process_run(record, args.jogs, Path(tmp), args.rate))
                print(f"run {len(runs)}: {'recorded' if record else 'unrecorded'} {runs[-1]['cpu_s']:.2f} s CPU", file=sys.stderr)
    on = statistics.median(r["cpu_s"] for r in runs if r["recorded"])
    off = statistics.median(r["cpu_s"] for r in runs if not r["recorded"])
    result = {"runs": runs, "cpu_s_recorded": on, "cpu_s_unrecorded": off, "overhead_pct": 100 * (on - off) / off,
              "goal_pct": 5.0, "jogs": args.jogs}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"| session work, unrecorded | {off:.2f} s CPU ({1e3 * off / args.jogs:.2f} ms per jog) |")
        print(f"| session work, recorded | {on:.2f} s CPU ({1e3 * on / args.jogs:.2f} ms per jog) |")
        print(f"| recording's cost | {result['overhead_pct']:+.1f} % (goal < 5 %) |")
        print(f"| messages written per run | {statistics.median(r['written'] for r in runs if r['recorded']):.0f}, "
              f"dropped {max(r['dropped'] for r in runs if r['recorded'])} |")
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=15.0, help="measured window per run")
    parser.add_argument("--rate", type=float, default=100.0, help="drag events per second")
    parser.add_argument("--pairs", type=int, default=3, help="recorded/unrecorded run pairs")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--processes", action="store_true", help="measure running teleprog up processes instead")
    parser.add_argument("--jogs", type=int, default=3000, help="jogs per in-process run")
    args = parser.parse_args()
    if not args.processes:
        return main_in_process(args)
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.pairs):
            for record in (i % 2 == 0, i % 2 != 0):  # alternate which goes first
                runs.append(one_run(record, args.seconds, args.rate, Path(tmp)))
                print(f"run {len(runs)}: {'recorded' if record else 'unrecorded'} {runs[-1]['cpu_pct']:.1f} % CPU, "
                      f"{runs[-1]['moves']} moves", file=sys.stderr)
    on = [r["cpu_s"] / r["wall_s"] for r in runs if r["recorded"]]
    off = [r["cpu_s"] / r["wall_s"] for r in runs if not r["recorded"]]
    on_m, off_m = statistics.median(on), statistics.median(off)
    result = {"runs": runs, "cpu_pct_recorded": 100 * on_m, "cpu_pct_unrecorded": 100 * off_m,
              "overhead_pct": 100 * (on_m - off_m) / off_m, "goal_pct": 5.0}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"| console CPU, unrecorded | {100 * off_m:.1f} % |")
        print(f"| console CPU, recorded | {100 * on_m:.1f} % |")
        print(f"| recording's cost | {result['overhead_pct']:+.1f} % of the unrecorded CPU (goal < 5 %) |")
        print(f"| messages written per recorded run | {statistics.median(r['written'] for r in runs if r['recorded']):.0f}, "
              f"dropped {max(r['dropped'] for r in runs if r['recorded'])} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
