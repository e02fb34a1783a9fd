"""Benchmark of ``teleprog up``: from the command to the robot connected over a 3 s link.

Runs the real ``python -m server.cli up`` (free ports, no recording, ``--delay-ms 3000``) with
``TELEPROG_STARTUP_TRACE=1``: every process (console, telerobot, link) logs
``startup-trace <process> <unix time> <event>`` lines on the console's stderr
(``shared.startup_trace``). The clock starts just before the command is launched; each event is
reported as seconds since then. The run ends at ``console robot connected``; the console is
then stopped (SIGTERM).

``handshake`` is the console's own measure of hello -> welcome (one round trip over the link:
2 x the delay when the robot is ready in time); ``rest`` is ``total - handshake``, the start-up
cost the delay does not hide. The goal of issue 21 is ``rest <= 1.5 s``.

The collision model cache (``TELEPROG_CACHE_DIR``) is warm unless ``--cold`` (a fresh empty
folder per run). Runs are sequential; the table shows each run and the median.

    .venv/bin/python benchmarks/bench_startup.py              # 3 runs, table
    .venv/bin/python benchmarks/bench_startup.py --runs 5 --json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

TRACE = re.compile(r"startup-trace (\w+) (\d+\.\d+) (.+)$")
HANDSHAKE = re.compile(r"handshake (\d+\.\d+) s")


def run_once(delay_ms: float, cache_dir: str | None, timeout_s: float = 90.0) -> dict:
    env = {**os.environ, "TELEPROG_STARTUP_TRACE": "1", "PYTHONUNBUFFERED": "1"}
    if cache_dir is not None:
        env["TELEPROG_CACHE_DIR"] = cache_dir
    cmd = [sys.executable, "-m", "server.cli", "up", "--port", "0", "--no-record", "--delay-ms", repr(float(delay_ms))]
    t0 = time.time()
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    events: list[tuple[float, str, str]] = []
    done = threading.Event()
    handshake: list[float] = []

    def read() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            m = TRACE.search(line.rstrip())
            if not m:
                continue
            events.append((float(m[2]) - t0, m[1], m[3]))
            if m[1] == "console" and m[3].startswith("robot connected"):
                h = HANDSHAKE.search(m[3])
                handshake.append(float(h[1]) if h else float("nan"))
                done.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        if not done.wait(timeout_s):
            raise SystemExit(f"bench_startup: the robot did not connect within {timeout_s:g} s")
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    total = max(t for t, p, e in events if p == "console" and e.startswith("robot connected"))
    return {"total_s": total, "handshake_s": handshake[0], "rest_s": total - handshake[0],
            "events": [{"t_s": round(t, 3), "process": p, "event": e} for t, p, e in sorted(events)]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--delay-ms", type=float, default=3000.0)
    parser.add_argument("--cold", action="store_true", help="an empty collision-model cache for every run")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    runs = []
    for _ in range(args.runs):
        if args.cold:
            with tempfile.TemporaryDirectory() as tmp:
                runs.append(run_once(args.delay_ms, tmp))
        else:
            runs.append(run_once(args.delay_ms, None))
    summary = {k: statistics.median(r[k] for r in runs) for k in ("total_s", "handshake_s", "rest_s")}
    result = {"delay_ms": args.delay_ms, "cold": args.cold, "load_1min_before": load,
              "load_1min_after": os.getloadavg()[0], "median": summary, "runs": runs}
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(f"teleprog up, {args.delay_ms:g} ms link, {'cold' if args.cold else 'warm'} cache; "
          f"load {load:.2f} before, {result['load_1min_after']:.2f} after")
    for i, r in enumerate(runs, 1):
        print(f"run {i}: total {r['total_s']:.2f} s, handshake {r['handshake_s']:.2f} s, rest {r['rest_s']:.2f} s")
    print(f"median: total {summary['total_s']:.2f} s, handshake {summary['handshake_s']:.2f} s, "
          f"rest {summary['rest_s']:.2f} s (goal: rest <= 1.5 s)")
    print("phases of the last run (s since the command):")
    for e in runs[-1]["events"]:
        print(f"  {e['t_s']:6.2f}  {e['process']:8s} {e['event']}")


if __name__ == "__main__":
    main()
