"""Console responsiveness while the operator drags: pipeline cost per event and event-to-scene latency.

Two measurements (issue 7, item 11):

* **pipeline**: the session's work for one gizmo event, in process: the jog (IK under the
  constraint), the collision check with interfering triangles and the control zone, automatic
  generation, and the fan-out of events to the scene's listeners; 2,000 events of a dragging
  motion at 100 Hz with generation on. The comparison is the bare kinematics of the same jog
  (``shared.robots.jog.jog_tool_to``), so the ratio shows what the rest of the pipeline adds.
* **end to end**: a running console (``teleprog up --no-robot``); each event is an HTTP jog call,
  and the latency runs until the session's event for it arrives on ``/api/events``: the same
  fan-out that redraws the viser scene (the browser's own rendering is not included).

Goals: 30 scene updates per second or more while dragging; event-to-scene p95 under 50 ms.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))


def drag_goals(session, n: int, rate_hz: float = 100.0, speed: float = 0.05) -> list[np.ndarray]:
    """Tool goals of an operator dragging the gizmo: a slow circle of 40 mm radius in the work
    plane around the start pose, ``speed`` m/s, one goal per event."""
    start = session.state.world_T_tcp.copy()
    radius = 0.04
    omega = speed / radius
    goals = []
    for k in range(n):
        t = k / rate_hz
        g = start.copy()
        g[0, 3] += radius * (np.cos(omega * t) - 1.0)
        g[1, 3] += radius * np.sin(omega * t)
        goals.append(g)
    return goals


def pipeline(events: int) -> dict:
    from server.session import Session
    from shared.cells.loader import DEFAULT_CELL, load_cell
    from shared.robots.jog import jog_tool_to

    cell = load_cell(DEFAULT_CELL)
    session = Session(cell)
    session.set_auto_generate(True)
    fanned = 0

    def listener(*_args) -> None:
        nonlocal fanned
        fanned += 1

    session.subscribe(listener)
    goals = drag_goals(session, events)
    times = np.empty(events)
    for k, goal in enumerate(goals):
        t0 = time.perf_counter()
        session.jog_tool_to(goal, frame="world", constraint="xy", motion="translate")
        times[k] = time.perf_counter() - t0
    session.release()
    statements = len(session.program_view().entries) - 1  # the trailing empty statement

    # the bare kinematics of the same events
    q = cell.q_home.copy()
    bare = np.empty(events)
    for k, goal in enumerate(goals):
        t0 = time.perf_counter()
        result = jog_tool_to(cell.robot, q, goal, frames=session.frames, frame="world", constraint="xy", motion="translate")
        bare[k] = time.perf_counter() - t0
        q = result.q
    session.close()
    return {
        "events": events,
        "pipeline_ms": {"mean": 1e3 * times.mean(), "p50": 1e3 * np.percentile(times, 50), "p95": 1e3 * np.percentile(times, 95)},
        "updates_per_s": 1.0 / times.mean(),
        "bare_jog_ms": {"mean": 1e3 * bare.mean(), "p95": 1e3 * np.percentile(bare, 95)},
        "ratio_bare_over_pipeline": bare.mean() / times.mean(),
        "listener_calls": fanned,
        "statements_generated": statements,
    }


async def _end_to_end(port: int, events: int) -> np.ndarray:
    import httpx
    from websockets.asyncio.client import connect

    lat = []
    async with httpx.AsyncClient(base_url=f"http://127.0.0.1:{port}", timeout=10) as http:
        async with connect(f"ws://127.0.0.1:{port}/api/events", max_size=None, compression=None) as ws:
            await ws.recv()  # the snapshot every subscriber gets first

            async def next_arm_event() -> None:
                while True:
                    if json.loads(await ws.recv()).get("type") == "arm":
                        return

            for k in range(events):
                delta = [0.0005 if (k // 50) % 2 == 0 else -0.0005, 0.0, 0.0]
                t0 = time.perf_counter()
                response = await http.post(
                    "/api/jog/tool", json={"frame": "world", "constraint": "xy", "motion": "translate", "displacement": delta}
                )
                if response.status_code >= 400:
                    raise RuntimeError(f"jog refused: {response.text}")
                try:
                    await asyncio.wait_for(next_arm_event(), 2.0)
                except asyncio.TimeoutError:
                    raise RuntimeError(f"event {k}: no arm event within 2 s of the jog") from None
                lat.append(time.perf_counter() - t0)
                await asyncio.sleep(0.01)
    return np.array(lat)


def end_to_end(events: int) -> dict:
    from support import free_port, stop_process, wait_http

    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "server.cli", "up", "--port", str(port), "--no-robot"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        wait_http(f"http://127.0.0.1:{port}/api/health", proc, timeout=120)
        lat = asyncio.run(_end_to_end(port, events))
    finally:
        stop_process(proc)
    return {"events": events, "latency_ms": {"p50": 1e3 * np.percentile(lat, 50), "p95": 1e3 * np.percentile(lat, 95), "max": 1e3 * lat.max()}}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--events", type=int, default=2000, help="gizmo events in the pipeline measurement")
    p.add_argument("--e2e-events", type=int, default=300, help="HTTP jog events through a running console (0: skip)")
    p.add_argument("--json", action="store_true")


def main_with(args: argparse.Namespace) -> int:
    out = {"pipeline": pipeline(args.events)}
    if args.e2e_events:
        out["end_to_end"] = end_to_end(args.e2e_events)
    out["load_average"] = os.getloadavg()[0]
    if args.json:
        print(json.dumps(out, default=float))
    else:
        p = out["pipeline"]
        print(f"pipeline: {p['pipeline_ms']['mean']:.2f} ms mean, {p['pipeline_ms']['p95']:.2f} ms p95 per event "
              f"= {p['updates_per_s']:.0f} updates/s (goal 30); bare jog {p['bare_jog_ms']['mean']:.2f} ms "
              f"(ratio {p['ratio_bare_over_pipeline']:.2f}x); {p['statements_generated']} statements generated")
        if "end_to_end" in out:
            e = out["end_to_end"]["latency_ms"]
            print(f"event -> session event: p50 {e['p50']:.1f} ms, p95 {e['p95']:.1f} ms (goal 50), max {e['max']:.1f} ms")
        print(f"load average {out['load_average']:.1f}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(parser)
    return main_with(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
