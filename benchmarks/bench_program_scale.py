"""The console's pace against the program's length (issue 35): a drag with generation on costs
the same at 10 statements as at 10,000.

* **in process** (``server.console.Session``, no robot): a program of N statements loaded
  (small joint moves), then an operator's drag of ``--jogs`` tool jogs of 0.5 mm along x,
  reversing every 10 jogs (5 mm strokes), with automatic generation on: the session's CPU time
  (``time.thread_time``) per jog, and per generated statement (the drag's CPU over the
  statements it generated). Goal: at 1,000 statements within 1.5x of that at 10.
* **real processes** (``teleprog up --delay-ms 300``: telerobot, link and console): the same
  program uploaded, then the same drag as HTTP jogs, back to back for ``--drag-s`` seconds, from
  this process. Reported: jogs a second the session took, the jogs' answer times, and the lag of
  the console's event loop during the drag (``GET /api/health?loop=true``: how late a task
  asking to wake every 10 ms woke). Goals: 30 jogs a second or more, loop lag p99 under 20 ms,
  no stall over 50 ms.

    .venv/bin/python benchmarks/bench_program_scale.py                    # table and plot, about 3 min
    .venv/bin/python benchmarks/bench_program_scale.py --sizes 10 1000 --json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

JOG_M = 0.5e-3
STROKE = 10


def program_text(cell, n: int) -> str:
    """``n`` small joint moves about the cell's home (valid from the home pose)."""
    j1 = float(np.degrees(cell.q_home[0]))
    return "\n".join(f"DRIVE J1 TO {j1 + (0.5 if i % 2 else -0.5):.2f} deg" for i in range(n)) + "\n"


def in_process(n: int, jogs: int) -> dict:
    from server.console import Session
    from shared.cells.loader import DEFAULT_CELL, load_cell

    cell = load_cell(DEFAULT_CELL)
    session = Session(cell)
    t0 = time.perf_counter()
    session.program.load(program_text(cell, n), "long.tp")
    load_s = time.perf_counter() - t0
    session.program.set_auto_generate(True)
    cpu = np.empty(jogs)
    for k in range(jogs):
        sign = 1.0 if (k // STROKE) % 2 == 0 else -1.0
        c0 = time.thread_time()
        session.arm.jog_tool(frame="world", constraint="x", motion="translate", displacement=np.array([sign * JOG_M, 0.0, 0.0]))
        cpu[k] = time.thread_time() - c0
    c0 = time.thread_time()
    session.arm.release()
    release = time.thread_time() - c0
    generated = len(session.program.view().entries) - 1 - n
    session.close()
    return {"statements": n, "load_s": load_s, "jogs": jogs, "generated": generated,
            "cpu_ms_per_jog": {"mean": 1e3 * cpu.mean(), "p95": 1e3 * float(np.percentile(cpu, 95)), "max": 1e3 * cpu.max()},
            "cpu_ms_per_generated": 1e3 * (cpu.sum() + release) / max(generated, 1)}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def real_processes(sizes: list[int], drag_s: float) -> list[dict]:
    import httpx

    from shared.cells.loader import DEFAULT_CELL, load_cell

    cell = load_cell(DEFAULT_CELL)
    port = _free_port()
    out = []
    with tempfile.TemporaryDirectory() as d:
        log = Path(d) / "console.log"
        proc = subprocess.Popen([sys.executable, "-m", "server.cli", "up", "--delay-ms", "300", "--no-record", "--port", str(port)],
                                stdout=log.open("w"), stderr=subprocess.STDOUT, cwd=ROOT, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        http = httpx.Client(base_url=f"http://127.0.0.1:{port}", headers={"X-Teleprog-Client": "bench"}, timeout=120)
        try:
            deadline = time.monotonic() + 180
            while True:
                try:
                    if http.get("/api/link").json().get("status") == "live":
                        break
                except httpx.HTTPError:
                    pass
                if time.monotonic() > deadline:
                    raise SystemExit(f"bench_program_scale: the console did not come up:\n{log.read_text()[-2000:]}")
                time.sleep(0.2)
            for n in sizes:
                http.post("/api/program/upload", params={"filename": "long.tp"}, content=program_text(cell, n).encode(),
                          headers={"content-type": "text/plain"}).raise_for_status()
                http.put("/api/program/auto", json={"on": True}).raise_for_status()
                http.get("/api/health", params={"loop": "reset"})
                answers, k = [], 0
                end = time.perf_counter() + drag_s
                while time.perf_counter() < end:
                    sign = 1.0 if (k // STROKE) % 2 == 0 else -1.0
                    t = time.perf_counter()
                    r = http.post("/api/jog/tool", json={"frame": "world", "constraint": "x", "motion": "translate",
                                                         "displacement": [sign * JOG_M * 1e3, 0.0, 0.0]})
                    answers.append(time.perf_counter() - t)
                    if r.status_code != 200:
                        raise SystemExit(f"bench_program_scale: jog {k}: {r.status_code} {r.text[:200]}")
                    k += 1
                lag = http.get("/api/health", params={"loop": "true"}).json()["loop"]
                http.post("/api/jog/release")
                a = np.array(answers)
                out.append({"statements": n, "jogs": k, "jogs_per_s": k / drag_s,
                            "answer_ms": {"median": 1e3 * float(np.median(a)), "p95": 1e3 * float(np.percentile(a, 95)), "max": 1e3 * a.max()},
                            "loop_lag": lag})
        finally:
            proc.terminate()
            proc.wait(20)
    return out


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = [r["statements"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(n, [r["cpu_ms_per_jog"]["mean"] for r in rows], "o-", label="per jog, mean")
    ax.plot(n, [r["cpu_ms_per_jog"]["p95"] for r in rows], "s--", label="per jog, p95")
    ax.plot(n, [r["cpu_ms_per_generated"] for r in rows], "^-", label="per generated statement")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("statements in the program")
    ax.set_ylabel("session CPU (ms)")
    ax.set_title("A drag with generation on, against program length")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000, 10000])
    p.add_argument("--jogs", type=int, default=400)
    p.add_argument("--drag-s", type=float, default=4.0)
    p.add_argument("--real-sizes", type=int, nargs="*", default=[10, 1000], help="sizes for the real-process drag ([] to skip)")
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    load = os.getloadavg()[0]
    in_proc = [in_process(n, a.jogs) for n in a.sizes]
    real = real_processes(a.real_sizes, a.drag_s) if a.real_sizes else []
    out = {"load_before": load, "load_after": os.getloadavg()[0], "in_process": in_proc, "real": real}
    base = next((r for r in in_proc if r["statements"] == 10), None)
    if base is not None:
        for r in in_proc:
            r["ratio_to_10"] = r["cpu_ms_per_jog"]["mean"] / base["cpu_ms_per_jog"]["mean"]
    figure = ROOT / "benchmarks" / "figures" / "program_scale.png"
    plot(in_proc, figure)
    if a.json:
        print(json.dumps(out, indent=2))
        return
    print(f"machine load {out['load_before']:.1f} -> {out['load_after']:.1f}; plot {figure.relative_to(ROOT)}\n")
    print("| statements | load (upload, parse, rules) | CPU per jog mean / p95 / max | ratio to 10 | generated | CPU per generated statement |")
    print("|---:|---:|---:|---:|---:|---:|")
    for r in in_proc:
        c = r["cpu_ms_per_jog"]
        print(f"| {r['statements']:,} | {r['load_s']:.2f} s | {c['mean']:.2f} / {c['p95']:.2f} / {c['max']:.1f} ms | "
              f"{r.get('ratio_to_10', float('nan')):.2f}x | {r['generated']} | {r['cpu_ms_per_generated']:.1f} ms |")
    if real:
        print("\n| statements (real processes, 300 ms link) | jogs a second | jog answer median / p95 / max | loop lag median / p99 / max | stalls over 50 ms |")
        print("|---:|---:|---:|---:|---:|")
        for r in real:
            lag, ans = r["loop_lag"], r["answer_ms"]
            print(f"| {r['statements']:,} | {r['jogs_per_s']:.1f} | {ans['median']:.1f} / {ans['p95']:.1f} / {ans['max']:.0f} ms | "
                  f"{lag['median_ms']:.1f} / {lag['p99_ms']:.1f} / {lag['max_ms']:.0f} ms | {lag['stalls_over_50ms']} |")


if __name__ == "__main__":
    main()
