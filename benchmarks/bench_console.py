"""Console responsiveness while the operator drags: pipeline cost per event, event-to-scene latency, frames in the browser.

Three measurements (issue 7, item 11):

* **pipeline**: the session's work for one gizmo event, in process: the jog (IK under the
  constraint), the collision check with interfering triangles and the control zone, automatic
  generation, and the fan-out of events to the scene's listeners; 2,000 events of a dragging
  motion at 100 Hz with generation on. The comparison is the bare kinematics of the same jog
  (``shared.robots.jog.jog_tool_to``), so the ratio shows what the rest of the pipeline adds.
  The same work's CPU time per event is also read back to back and with the events 10 ms apart,
  as a drag spaces them: on a shared virtual machine a pause makes the next event's work slower.
* **end to end**: a running console (``teleprog up --no-robot``); each event is an HTTP jog call,
  and the latency runs until the session's event for it arrives on ``/api/events``: the same
  fan-out that redraws the viser scene (the browser's own rendering is not included).
* **browser**: the page in headless Chromium (Debian's ``chromium`` driven by Playwright) on a
  running ``teleprog up --delay-ms 200`` with automatic generation on, while the mouse drags the
  gizmo's x arrow back and forth: the page's frame times (``requestAnimationFrame`` timestamps),
  the frames in which WebGL actually drew (draw calls counted by a wrapper installed before the
  page loads), the viser WebSocket windows that carry scene changes (decoded from the frames the
  page receives) and the session's ``arm`` events per second. Headless Chromium renders WebGL in
  software (SwiftShader) here: the frame times are those of a CPU renderer sharing two cores with
  the console, not of an operator's GPU.
* **page input**: in the same page, the gizmo pressed with the real mouse, 60 pointer moves a
  second dispatched on the 3D canvas (``ConsolePage.pointer_sweep``; headless Chromium would hand
  real mouse moves over only once per drawn frame). Recorded in the page's clock at the boundary
  of viser's WebSocket worker: when the page hands over a gizmo update, and when a batch of scene
  messages that moves the virtual arm comes back. Per move: time to the next send, to the reply
  that moves the arm (the scene update), and to the first drawn frame after that.

* **program length** (``--program-sizes 10 100 1000 10000``): the same drag of 0.5 mm jogs with
  generation on against programs of those sizes, in process (CPU per jog) and, at
  ``--program-real-sizes``, as HTTP jogs on real processes with the robot attached through a
  300 ms link (jogs a second, the console loop's lag); ``benchmarks/bench_program_scale.py`` does
  the work and draws its plot. Goals (issue 35): at 1,000 statements within 1.5x of 10; 30 jogs a
  second; loop lag p99 under 20 ms and no stall over 50 ms.

The HTTP jogs move 0.5 mm each (the API takes millimetres): a real drag's step, not a cached one.

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
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))


SPACED_GAP_S = 0.01
SPACED_EVENTS = 300
"""The pipeline's CPU time per event is also measured back to back and with events this far apart."""


def drag_goals(session, n: int, rate_hz: float = 100.0, speed: float = 0.05) -> list[np.ndarray]:
    """Tool goals of an operator dragging the gizmo: a slow circle of 40 mm radius in the work
    plane around the start pose, ``speed`` m/s, one goal per event."""
    start = session.arm.state.world_T_tcp.copy()
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
    from server.console import Session
    from shared.cells.loader import DEFAULT_CELL, load_cell
    from shared.robots.jog import jog_tool_to

    cell = load_cell(DEFAULT_CELL)
    session = Session(cell)
    session.program.set_auto_generate(True)
    fanned = 0

    def listener(*_args) -> None:
        nonlocal fanned
        fanned += 1

    session.arm.subscribe(listener)
    goals = drag_goals(session, events)
    times = np.empty(events)
    for k, goal in enumerate(goals):
        t0 = time.perf_counter()
        session.arm.jog_tool_to(goal, frame="world", constraint="xy", motion="translate")
        times[k] = time.perf_counter() - t0
    # the same work's CPU time with the events back to back, then spaced as a drag spaces them
    # (10 ms apart): how much a pause costs the next event on this machine (caches, clocks)
    spaced = {}
    for gap_s in (0.0, SPACED_GAP_S):
        cpu = np.full(min(SPACED_EVENTS, len(goals)), np.nan)  # fewer events asked: fewer read
        for k, goal in enumerate(goals[:SPACED_EVENTS]):
            if gap_s:
                time.sleep(gap_s)
            c0 = time.thread_time()
            session.arm.jog_tool_to(goal, frame="world", constraint="xy", motion="translate")
            cpu[k] = time.thread_time() - c0
        spaced["back_to_back" if gap_s == 0.0 else "spaced"] = 1e3 * float(cpu[min(20, cpu.size // 2):].mean())
    session.arm.release()
    statements = len(session.program.view().entries) - 1  # the trailing empty statement

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
        "cpu_ms_per_event": {**spaced, "gap_ms": 1e3 * SPACED_GAP_S, "events": SPACED_EVENTS},
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
                delta = [0.5 if (k // 50) % 2 == 0 else -0.5, 0.0, 0.0]  # mm, as the API takes it: a real drag's 0.5 mm
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


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds a process has used (Linux ``/proc``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _jog_cpu(port: int, pid: int, events: int, idle_s: float) -> tuple[np.ndarray, float, float]:
    """Latencies of ``events`` jogs, and the console's CPU per jog with its idle CPU over the same
    time (telemetry, heartbeats) taken off: (latencies, cpu ms per jog, idle cpu ms per s)."""
    c0 = _cpu_s(pid)
    time.sleep(idle_s)
    idle_rate = (_cpu_s(pid) - c0) / idle_s
    t0 = time.perf_counter()
    c1 = _cpu_s(pid)
    lat = asyncio.run(_end_to_end(port, events))
    busy = _cpu_s(pid) - c1
    wall = time.perf_counter() - t0
    return lat, 1e3 * max(0.0, busy - idle_rate * wall) / events, 1e3 * idle_rate


def end_to_end(events: int, with_robot: bool = False) -> dict:
    """HTTP jogs through a running console: latency to the session's event and the console
    process's CPU per jog (no page attached). ``with_robot``: the telerobot and a 200 ms link
    run too (telemetry at 50 Hz drives the remote ghost and the monitor meanwhile)."""
    from support import free_port, stop_process, wait_http

    port = free_port()
    extra = ["--delay-ms", "200", "--no-record"] if with_robot else ["--no-robot"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "server.cli", "up", "--port", str(port), *extra],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        wait_http(f"http://127.0.0.1:{port}/api/health", proc, timeout=120)
        asyncio.run(_end_to_end(port, 50))  # warm-up: first calls compile and fill caches
        lat, cpu_ms, idle_ms_per_s = _jog_cpu(port, proc.pid, events, idle_s=5.0)
    finally:
        stop_process(proc)
    return {"events": events, "with_robot": with_robot,
            "latency_ms": {"p50": 1e3 * np.percentile(lat, 50), "p95": 1e3 * np.percentile(lat, 95), "max": 1e3 * lat.max()},
            "console_cpu_ms_per_jog": cpu_ms, "console_idle_cpu_ms_per_s": idle_ms_per_s}


# -- the page in headless Chromium ---------------------------------------------------------------

# Installed before the page's own scripts: count WebGL draw calls, so a frame in which the scene
# was actually redrawn can be told from an idle one (viser renders on demand).
COUNT_DRAWS_JS = """
(() => {
  window.__tp = {draws: 0, run: 0, t: [], d: [], long: [], drawStarts: [], lastDraw: -1e9};
  try {  // main-thread tasks over 50 ms: the page's own JavaScript, as opposed to the renderer
    new PerformanceObserver((list) => {
      for (const e of list.getEntries()) window.__tp.long.push([e.startTime, e.duration]);
    }).observe({type: "longtask", buffered: true});
  } catch (e) {}
  for (const ctx of [window.WebGL2RenderingContext, window.WebGLRenderingContext]) {
    if (!ctx) continue;
    for (const name of ["drawElements", "drawArrays", "drawElementsInstanced", "drawArraysInstanced", "drawRangeElements"]) {
      const original = ctx.prototype[name];
      if (typeof original !== "function") continue;
      ctx.prototype[name] = function (...args) {
        const tp = window.__tp; const now = performance.now();
        if (now - tp.lastDraw > 4) tp.drawStarts.push(now);  // the first draw call of a drawn frame
        tp.lastDraw = now; tp.draws++;
        return original.apply(this, args);
      };
    }
  }
})();
"""
# One timestamp and the draw count per animation frame until stopped.
# (a loop left over from an earlier recording sees a newer ``run`` and ends without writing)
START_FRAMES_JS = """() => {
  const tp = window.__tp; tp.t = []; tp.d = []; tp.run = (tp.run || 0) + 1;
  const run = tp.run;
  const frame = (now) => {
    if (tp.run !== run) return;
    tp.t.push(now); tp.d.push(tp.draws); requestAnimationFrame(frame);
  };
  requestAnimationFrame(frame);
}"""
STOP_FRAMES_JS = "() => { const tp = window.__tp; tp.run += 1; return {t: tp.t, d: tp.d, long: tp.long}; }"

# Installed before the page's own scripts: viser talks to its WebSocket through a worker. Record,
# in the page's clock, when the page hands the worker a gizmo update to send (with the gizmo's x),
# and when a decoded batch of messages arrives from it, whether the batch moves the virtual arm
# (/robot/link*) and the x of the last link it places (to pair replies with sends by content).
RECORD_SOCKET_JS = """
(() => {
  const rec = window.__tpInput = {sent: [], batches: []};
  const Original = window.Worker;
  if (!Original) return;
  window.Worker = class extends Original {
    constructor(...args) {
      super(...args);
      this.addEventListener("message", (e) => {
        const d = e.data;
        if (!d || d.type !== "message_batch") return;
        let arm = false, link = -1, x = null;
        for (const m of d.messages) {
          const found = typeof m.name === "string" && /^\\/robot\\/link(\\d+)$/.exec(m.name);
          if (!found || !/Position|Orientation|Pose/.test(m.type)) continue;
          arm = true;
          if (m.position && +found[1] > link) { link = +found[1]; x = m.position[0]; }
        }
        rec.batches.push([performance.now(), arm, x]);
      });
    }
    postMessage(data, ...rest) {
      if (data && data.type === "send" && data.message && data.message.type === "TransformControlsUpdateMessage")
        rec.sent.push([performance.now(), data.message.position[0]]);
      return super.postMessage(data, ...rest);
    }
  };
})();
"""
RESET_SOCKET_RECORD_JS = "() => { const r = window.__tpInput; r.sent = []; r.batches = []; window.__tp.drawStarts = []; }"
READ_SOCKET_RECORD_JS = "() => ({...window.__tpInput, drawStarts: window.__tp.drawStarts})"


# viser messages that change the 3D scene (the rest change the GUI panel)
SCENE_UPDATES = {"SetPositionMessage", "SetOrientationMessage", "SetSceneNodeVisibilityMessage",
                 "SceneNodeUpdateMessage", "RemoveSceneNodeMessage", "SetBoneOrientationMessage",
                 "SetBonePositionMessage"}


def _scene_message_types() -> set[str]:
    import viser._messages as messages

    pending, names = [messages._CreateSceneNodeMessage], set()
    while pending:  # every subclass: the messages that (re)create a scene node
        for sub in pending.pop().__subclasses__():
            names.add(sub.__name__)
            pending.append(sub)
    return names | SCENE_UPDATES


def viser_window_types(payload: bytes) -> list[str]:
    """The message types in one WebSocket frame of viser 1.x: 8 bytes decompressed size, 8 bytes
    compressed size, zstd-compressed msgpack ``{"messages": [...]}``, then raw buffers."""
    import msgspec
    import zstandard

    size, packed = int.from_bytes(payload[:8], "little"), int.from_bytes(payload[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(payload[16 : 16 + packed], max_output_size=size)
    return [m.get("type", "?") for m in msgspec.msgpack.decode(inner).get("messages", ())]


def _frame_stats(t_ms: list[float], draws: list[int], long_tasks: list[list[float]] = ()) -> dict:
    """Frame rate and frame times from per-frame timestamps (ms) and cumulative draw counts; a
    frame that outlasts the whole window leaves too few timestamps and reads as NaN."""
    t = np.asarray(t_ms, dtype=float)
    d = np.asarray(draws, dtype=float)
    if len(t) < 3:
        nan = float("nan")
        return {"seconds": nan, "frames": max(len(t) - 1, 0), "fps": nan, "frame_ms": {"p50": nan, "p95": nan, "max": nan},
                "rendered_frames": 0, "draw_calls_per_rendered_frame": nan, "rendered_fps": nan,
                "render_interval_ms": {"p50": nan, "p95": nan}, "main_thread_long_task_share": nan}
    dt = np.diff(t)
    span = (t[-1] - t[0]) / 1e3
    js_ms = sum(d_ms for start, d_ms in long_tasks if t[0] <= start <= t[-1])
    drawn = np.flatnonzero(np.diff(d) > 0) + 1  # frames during which WebGL drew
    drawn_dt = np.diff(t[drawn]) if len(drawn) > 1 else np.array([np.nan])
    return {
        "seconds": span,
        "frames": int(len(dt)),
        "fps": len(dt) / span,
        "frame_ms": {"p50": float(np.percentile(dt, 50)), "p95": float(np.percentile(dt, 95)), "max": float(dt.max())},
        "rendered_frames": int(len(drawn)),
        "draw_calls_per_rendered_frame": float((d[-1] - d[0]) / len(drawn)) if len(drawn) else float("nan"),
        "rendered_fps": len(drawn) / span,
        "render_interval_ms": {"p50": float(np.nanpercentile(drawn_dt, 50)), "p95": float(np.nanpercentile(drawn_dt, 95))},
        "main_thread_long_task_share": js_ms / 1e3 / span,
    }


@dataclass(frozen=True)
class Percentiles:
    """p50, p95 and max of a sample (ms), and its size."""

    p50: float
    p95: float
    max: float
    n: int

    @classmethod
    def of(cls, values: list[float]) -> "Percentiles":
        v = np.asarray(values, float)
        if not len(v):
            return cls(float("nan"), float("nan"), float("nan"), 0)
        return cls(float(np.percentile(v, 50)), float(np.percentile(v, 95)), float(v.max()), int(len(v)))


@dataclass(frozen=True)
class PageInputStats:
    """The page fed pointer moves: rates over the moves' span and per-move latencies (page clock)."""

    seconds: float
    requested_hz: float
    moves_per_s: float
    gizmo_sends_per_s: float
    arm_updates_per_s: float
    drawn_frames_per_s: float
    #: share of the sends whose reply was found by content (the rest were superseded in flight)
    sends_answered: float
    move_to_send_ms: Percentiles
    move_to_scene_update_ms: Percentiles
    move_to_drawn_frame_ms: Percentiles
    session_arm_events_per_s: float = float("nan")


#: a reply answers a send when its last link's x is the send's gizmo x plus the fixed offset
#: between that link and the tool (the drag translates along x only), to this tolerance (m)
SAME_X_M = 1e-6


def _reply_times(sent: list[list[float]], batches: list[list]) -> tuple[np.ndarray, float]:
    """For each send, when the page received the scene update answering it, paired by content.

    The drag translates the tool along x, so the last link's x in a reply equals the gizmo's x in
    the send it answers plus a constant (the median of reply x minus latest earlier send x). A
    reply answers the latest earlier send with that x. A send without a reply of its own (its
    update was superseded or refused) takes the first reply to a later send: the pose shown then
    already includes its move. NaN where no later reply came in the window. Also returns the
    share of sends answered by a reply of their own."""
    send_t = np.array([t for t, _ in sent], float)
    send_x = np.array([x for _, x in sent], float)
    replies = [(t, x) for t, moves_arm, x in batches if moves_arm and x is not None]
    answered = np.full(len(send_t), np.inf)
    if not replies or not len(send_t):
        return np.full(len(send_t), np.nan), 0.0
    rep_t = np.array([t for t, _ in replies], float)
    rep_x = np.array([x for _, x in replies], float)
    latest = np.searchsorted(send_t, rep_t) - 1
    offset = float(np.median(rep_x[latest >= 0] - send_x[latest[latest >= 0]]))
    for t, x, last in zip(rep_t, rep_x, latest):
        match = np.flatnonzero(np.abs(send_x[: last + 1] + offset - x) < SAME_X_M)
        if match.size:
            answered[match[-1]] = min(answered[match[-1]], t)
    effective = np.minimum.accumulate(answered[::-1])[::-1]  # a later send's reply covers earlier ones
    return np.where(np.isfinite(effective), effective, np.nan), float(np.isfinite(answered).mean())


def _input_stats(dispatched: list[float], sent: list[list[float]], batches: list[list], draw_starts: list[float],
                 requested_hz: float) -> PageInputStats:
    """Latencies (page clock, ms) from each dispatched pointer move to (a) the page's next gizmo
    send, (b) the arrival of the scene update answering that send (``_reply_times``) and (c) the
    first draw call of the next drawn frame after it; rates counted over the moves' span."""
    d = np.asarray(dispatched, float)
    reply, answered_share = _reply_times(sent, batches)
    send_t = np.array([t for t, _ in sent], float)
    draws = np.asarray(draw_starts, float)
    to_send, to_update, to_drawn = [], [], []
    for when in d:
        k = int(np.searchsorted(send_t, when))
        if k == len(send_t) or not np.isfinite(reply[k]):
            continue  # the last moves: nothing answered them within the window
        to_send.append(send_t[k] - when)
        to_update.append(reply[k] - when)
        j = int(np.searchsorted(draws, reply[k]))
        if j < len(draws):
            to_drawn.append(draws[j] - when)
    t0, t1 = d[0], d[-1]
    span = (t1 - t0) / 1e3

    def rate(times) -> float:
        times = np.asarray(times, float)
        return float(((times >= t0) & (times <= t1)).sum() / span)

    return PageInputStats(
        seconds=span, requested_hz=requested_hz, moves_per_s=(len(d) - 1) / span,
        gizmo_sends_per_s=rate(send_t), arm_updates_per_s=rate([t for t, moves_arm, _ in batches if moves_arm]),
        drawn_frames_per_s=rate(draws), sends_answered=answered_share,
        move_to_send_ms=Percentiles.of(to_send), move_to_scene_update_ms=Percentiles.of(to_update),
        move_to_drawn_frame_ms=Percentiles.of(to_drawn),
    )


def _find_gizmo_grab(ui, cx: float, cy: float, scale: float) -> float:
    """Offset right of the canvas centre where a short drag moves the tool along world x (the
    camera looks at the tool from -y; offsets found for a 900 px high view, times ``scale``);
    the probe drag is undone with a drag back."""
    for grab in (40 * scale, 55 * scale, 30 * scale, 70 * scale, 25 * scale):
        before = ui.session()["arm"]["tool_xyz_mm"][0]
        ui.drag(cx + grab, cy, cx + grab + 30 * scale, cy)
        time.sleep(0.6)
        moved = ui.session()["arm"]["tool_xyz_mm"][0] - before
        if abs(moved) > 1.0:
            ui.drag(cx + grab + 30 * scale, cy, cx + grab, cy)
            time.sleep(0.6)
            return float(grab)
    raise RuntimeError("no grab point on the gizmo's x arrow moved the tool")


def _settle(page, limit_s: float = 20.0) -> None:
    """Wait (up to ``limit_s``) for a second in which the page's JavaScript ran no long task: the
    first seconds of the page compile shaders and lay out the panel, which is not what is timed."""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        page.evaluate(START_FRAMES_JS)
        page.wait_for_timeout(1000)
        raw = page.evaluate(STOP_FRAMES_JS)
        if len(raw["t"]) > 2 and not any(raw["t"][0] <= start <= raw["t"][-1] for start, _ in raw["long"]):
            return


def browser(seconds: float, idle_seconds: float = 5.0, amplitude_px: float = 60.0, period_s: float = 2.0,
            viewport: tuple[int, int] = (1400, 900), input_seconds: float = 5.0, input_hz: float = 60.0,
            fixed_dpr: float | None = None) -> dict:
    """Drag the gizmo in the page for ``seconds`` and measure frames and scene updates there; then
    hold it pressed and feed ``input_hz`` pointer moves a second for ``input_seconds`` (0: skip)."""
    import tempfile

    from playwright.sync_api import sync_playwright

    sys.path.insert(0, str(ROOT / "tests" / "browser"))
    from console_page import ConsolePage
    from support import CHROMIUM_ARGS, EventFeed, start_console, stop_process

    executable = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    if not Path(executable).exists():
        raise RuntimeError(f"Debian's chromium is needed ({executable} not found)")
    scene_types = _scene_message_types()
    console = start_console(Path(tempfile.mkdtemp(prefix="bench_console_")), "--delay-ms", "200")
    frames: list[tuple[float, bytes]] = []  # (arrival, payload) of the viser socket's frames
    events = None
    try:
        # generated statements stay in the program (quasi regime): the robot stays idle
        for method, path, body in (("PUT", "/api/regime", {"regime": "quasi"}), ("PUT", "/api/program/auto", {"on": True})):
            r = console.api(method, path, json=body)
            if r.status_code >= 400:
                raise RuntimeError(f"{method} {path}: {r.status_code} {r.text}")
        with sync_playwright() as pw:
            chromium = pw.chromium.launch(executable_path=executable, headless=True, args=CHROMIUM_ARGS)
            context = chromium.new_context(viewport={"width": viewport[0], "height": viewport[1]})
            page = context.new_page()
            page.add_init_script(COUNT_DRAWS_JS)
            page.add_init_script(RECORD_SOCKET_JS)

            def on_socket(ws) -> None:
                if "/viser" in ws.url:
                    ws.on("framereceived", lambda payload: frames.append((time.perf_counter(), payload)))

            page.on("websocket", on_socket)
            ui = ConsolePage(page, console)
            # viser's URL setting fixedDpr: the 3D view drawn at that many device pixels per CSS
            # pixel (by default viser adapts it between 0.75 and 1 by the measured frame rate)
            ui.open(f"fixedDpr={fixed_dpr}" if fixed_dpr else "")
            renderer = page.evaluate(
                "() => { const gl = document.createElement('canvas').getContext('webgl2');"
                " const ext = gl && gl.getExtension('WEBGL_debug_renderer_info');"
                " return ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : (gl ? gl.getParameter(gl.RENDERER) : 'none'); }"
            )
            cx, cy = ui.canvas_center()
            scale = page.locator("canvas").first.bounding_box()["height"] / 900.0
            grab = _find_gizmo_grab(ui, cx, cy, scale)
            amplitude_px *= scale
            events = EventFeed(console.url)  # closed in the finally below
            page.mouse.move(cx - 200, cy + 200)
            _settle(page)
            # the page at rest (the robot idle, its telemetry still arriving)
            page.evaluate(START_FRAMES_JS)
            i0 = time.perf_counter()
            page.wait_for_timeout(idle_seconds * 1e3)
            i1 = time.perf_counter()
            raw = page.evaluate(STOP_FRAMES_JS)
            idle = _frame_stats(raw["t"], raw["d"], raw["long"])
            x0 = cx + grab
            # pointer moves at a display's rate, fed to the gizmo pressed with the real mouse
            page_input = None
            if input_seconds:
                page.mouse.move(x0, cy)
                time.sleep(0.15)
                page.mouse.down()
                page.evaluate(START_FRAMES_JS)
                page.evaluate(RESET_SOCKET_RECORD_JS)
                e0 = time.perf_counter()
                dispatched = ui.pointer_sweep(x0, cy, amplitude_px, input_hz, input_seconds, period_s)
                e1 = time.perf_counter()
                time.sleep(0.3)  # the last replies
                page.evaluate(STOP_FRAMES_JS)
                record = page.evaluate(READ_SOCKET_RECORD_JS)
                page.mouse.up()
                if not record["sent"]:
                    raise RuntimeError("the pointer moves did not drag the gizmo (no update sent)")
                page_input = _input_stats(dispatched, record["sent"], record["batches"], record["drawStarts"], input_hz)
                time.sleep(0.5)
            # the drag with the real mouse: press on the x arrow, sweep it left and right, let go
            page.mouse.move(x0, cy)
            time.sleep(0.15)
            page.mouse.down()
            entries_before = len(ui.session()["program"]["entries"])
            page.evaluate(START_FRAMES_JS)
            t0 = time.perf_counter()
            moves = 0
            while (t := time.perf_counter() - t0) < seconds:
                page.mouse.move(x0 + amplitude_px * np.sin(2 * np.pi * t / period_s), cy)
                moves += 1
                time.sleep(0.005)
            t1 = time.perf_counter()
            raw = page.evaluate(STOP_FRAMES_JS)
            page.mouse.up()
            time.sleep(0.8)
            drag = _frame_stats(raw["t"], raw["d"], raw["long"])
            statements = len(ui.session()["program"]["entries"]) - entries_before
            context.close()
            chromium.close()
        arm_events_drag, arm_events_idle = len(events.between(t0, t1)), len(events.between(i0, i1))
        if page_input is not None:
            page_input = replace(page_input, session_arm_events_per_s=len(events.between(e0, e1)) / (e1 - e0))
    finally:
        if events is not None:
            events.close()
        stop_process(console.proc)

    def windows(a: float, b: float) -> dict:
        chosen = [p for (t, p) in frames if a <= t <= b and isinstance(p, bytes | bytearray)]
        kinds = [viser_window_types(bytes(p)) for p in chosen]
        scene = sum(1 for k in kinds if any(name in scene_types for name in k))
        return {"windows": len(chosen), "windows_per_s": len(chosen) / (b - a),
                "scene_windows": scene, "scene_updates_per_s": scene / (b - a),
                "scene_messages": sum(1 for k in kinds for name in k if name in scene_types)}

    drag.update(windows(t0, t1))
    idle.update(windows(i0, i1))
    drag.update({"mouse_moves_per_s": moves / (t1 - t0), "arm_events_per_s": arm_events_drag / (t1 - t0),
                 "statements_generated": statements})
    idle.update({"arm_events_per_s": arm_events_idle / (i1 - i0)})
    uptime = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    return {"renderer": renderer, "viewport": list(viewport), "fixed_dpr": fixed_dpr, "drag": drag, "idle": idle,
            "page_input": asdict(page_input) if page_input is not None else None, "uptime": uptime,
            "load_average": list(os.getloadavg())}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--events", type=int, default=2000, help="gizmo events in the pipeline measurement")
    p.add_argument("--e2e-events", type=int, default=300, help="HTTP jog events through a running console (0: skip)")
    p.add_argument("--browser-seconds", type=float, default=10.0,
                   help="seconds of gizmo dragging in headless Chromium (0: skip)")
    p.add_argument("--browser-viewport", default="1400x900", help="page size in CSS pixels, WIDTHxHEIGHT")
    p.add_argument("--input-seconds", type=float, default=5.0,
                   help="seconds of pointer moves fed to the pressed gizmo in the page (0: skip)")
    p.add_argument("--input-hz", type=float, default=60.0, help="rate of those pointer moves")
    p.add_argument("--browser-dpr", type=float, default=None,
                   help="draw the 3D view at this fixed device pixel ratio (viser's fixedDpr; default: viser adapts it)")
    p.add_argument("--program-sizes", type=int, nargs="*", default=[],
                   help="also the drag against the program's length: programs of these sizes (10 100 1000 10000), "
                        "in process (benchmarks/bench_program_scale.py)")
    p.add_argument("--program-real-sizes", type=int, nargs="*", default=[10, 1000],
                   help="with --program-sizes: the same drag as HTTP jogs on real processes at these sizes")
    p.add_argument("--json", action="store_true")


def program_scale(sizes: list[int], real_sizes: list[int]) -> dict:
    """The drag of 0.5 mm jogs with generation on against the program's length (issue 35)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_program_scale as scale

    rows = [scale.in_process(n, 400) for n in sizes]
    base = rows[0]["cpu_ms_per_jog"]["mean"]
    for r in rows:
        r["ratio_to_smallest"] = r["cpu_ms_per_jog"]["mean"] / base
    return {"in_process": rows, "real_processes": scale.real_processes(real_sizes, 4.0) if real_sizes else []}


def main_with(args: argparse.Namespace) -> int:
    out = {"pipeline": pipeline(args.events)}
    if args.program_sizes:
        out["program_scale"] = program_scale(args.program_sizes, args.program_real_sizes)
    if args.e2e_events:
        out["end_to_end"] = end_to_end(args.e2e_events)
        out["end_to_end_robot"] = end_to_end(args.e2e_events, with_robot=True)
    if args.browser_seconds:
        width, height = (int(v) for v in args.browser_viewport.lower().split("x"))
        out["browser"] = browser(args.browser_seconds, viewport=(width, height), input_seconds=args.input_seconds,
                                 input_hz=args.input_hz, fixed_dpr=args.browser_dpr)
    out["load_average"] = os.getloadavg()[0]
    if args.json:
        print(json.dumps(out, default=float))
    else:
        p = out["pipeline"]
        print(f"pipeline: {p['pipeline_ms']['mean']:.2f} ms mean, {p['pipeline_ms']['p95']:.2f} ms p95 per event "
              f"= {p['updates_per_s']:.0f} updates/s (goal 30); bare jog {p['bare_jog_ms']['mean']:.2f} ms "
              f"(ratio {p['ratio_bare_over_pipeline']:.2f}x); {p['statements_generated']} statements generated")
        c = p["cpu_ms_per_event"]
        print(f"pipeline CPU per event: {c['back_to_back']:.2f} ms back to back, {c['spaced']:.2f} ms with events "
              f"{c['gap_ms']:.0f} ms apart")
        for key, what in (("end_to_end", "no robot"), ("end_to_end_robot", "robot on a 200 ms link")):
            if key in out:
                e = out[key]["latency_ms"]
                print(f"HTTP jog -> session event ({what}): p50 {e['p50']:.1f} ms, p95 {e['p95']:.1f} ms (goal 50), "
                      f"max {e['max']:.1f} ms; console CPU {out[key]['console_cpu_ms_per_jog']:.2f} ms a jog (goal 2) "
                      f"over its idle {out[key]['console_idle_cpu_ms_per_s']:.0f} ms/s")
        if "browser" in out:
            b = out["browser"]
            for name in ("idle", "drag"):
                f = b[name]
                print(f"browser {name}: {f['fps']:.1f} frames/s, frame p50 {f['frame_ms']['p50']:.1f} ms, "
                      f"p95 {f['frame_ms']['p95']:.1f} ms, max {f['frame_ms']['max']:.0f} ms; "
                      f"{f['rendered_fps']:.1f} rendered frames/s; {f['scene_updates_per_s']:.1f} scene updates/s "
                      f"({f['windows_per_s']:.1f} viser windows/s); {f['arm_events_per_s']:.1f} session arm events/s; "
                      f"{f['draw_calls_per_rendered_frame']:.0f} draw calls per rendered frame; page JavaScript in long tasks "
                      f"{100 * f['main_thread_long_task_share']:.0f}% of the time")
            if b["page_input"] is not None:
                q = b["page_input"]
                print(f"page input: {q['moves_per_s']:.1f} pointer moves/s -> {q['gizmo_sends_per_s']:.1f} gizmo sends/s -> "
                      f"{q['arm_updates_per_s']:.1f} arm scene updates/s received (goal 30; {q['session_arm_events_per_s']:.1f} "
                      f"session arm events/s), {q['drawn_frames_per_s']:.1f} drawn frames/s; move -> scene update "
                      f"p50 {q['move_to_scene_update_ms']['p50']:.1f} ms, p95 {q['move_to_scene_update_ms']['p95']:.1f} ms (goal 50); "
                      f"move -> send p95 {q['move_to_send_ms']['p95']:.1f} ms; move -> drawn frame p50 "
                      f"{q['move_to_drawn_frame_ms']['p50']:.0f} ms, p95 {q['move_to_drawn_frame_ms']['p95']:.0f} ms; "
                      f"{100 * q['sends_answered']:.0f}% of sends answered by a reply of their own")
            print(f"browser drag: {b['drag']['mouse_moves_per_s']:.0f} mouse moves/s, "
                  f"{b['drag']['statements_generated']} statements generated; renderer {b['renderer']}; {b['uptime']}")
        for r in out.get("program_scale", {}).get("in_process", []):
            c = r["cpu_ms_per_jog"]
            print(f"program of {r['statements']:,}: CPU per jog {c['mean']:.2f} ms mean, {c['p95']:.2f} p95, {c['max']:.1f} max "
                  f"({r['ratio_to_smallest']:.2f}x the smallest; goal 1.5x at 1,000 against 10)")
        for r in out.get("program_scale", {}).get("real_processes", []):
            lag = r["loop_lag"]
            print(f"program of {r['statements']:,}, real processes: {r['jogs_per_s']:.0f} jogs/s (goal 30); loop lag "
                  f"p99 {lag['p99_ms']:.1f} ms (goal 20), max {lag['max_ms']:.0f} ms, {lag['stalls_over_50ms']} stalls over 50 ms (goal 0)")
        print(f"load average {out['load_average']:.1f}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(parser)
    return main_with(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
