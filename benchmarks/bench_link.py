"""Benchmark of the delayed link (``teleprog link``) against a plain websockets echo.

Work: a 50 Hz stream of real telemetry frames (174 bytes) on ``/telemetry`` while bursts of 1,000
statements go out on ``/command``, each statement its own command unit (the worst case for
per-message cost), every message echoed back by a plain websockets server. Three set-ups, all on
loopback on this machine:

* ``echo``: client <-> echo server (websockets, no link): the reference;
* ``link 0 ms``: client <-> ``teleprog link --delay-ms 0`` <-> echo: what the relay itself costs;
* ``link 3000 ms``: the same with the default 3 s each way: what the relay adds over the set
  delay (round trip minus 2 x 3 s).

Each set-up runs once with the 50 Hz stream alone and once with bursts on top. Figures:
round-trip time of telemetry frames (p50, p99, max), burst time (first unit sent to last unit
echoed, minus the set delays) and burst throughput. Ratios are ``echo / link`` for the same work.

    .venv/bin/python benchmarks/bench_link.py            # table
    .venv/bin/python benchmarks/bench_link.py --json
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from websockets.asyncio.client import connect
from websockets.asyncio.server import serve

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from shared.language.statements import Drive  # noqa: E402
from shared.wire.messages import ControlMode, RobotState  # noqa: E402
from shared.wire.telemetry import TelemetryFrame, encode_frame  # noqa: E402
from shared.wire.units import encode_unit  # noqa: E402
from support import free_port, wait_http  # noqa: E402

TAG = struct.Struct("<Id")  # message number, send time (perf_counter), overwritten into each payload


async def _echo(ws) -> None:
    async for message in ws:
        await ws.send(message)


async def run_echo_server(port: int) -> None:
    async with serve(_echo, "127.0.0.1", port, compression=None, max_size=None, ping_interval=None):
        await asyncio.Future()


def _frame_payload(k: int) -> bytes:
    frame = TelemetryFrame(time=k / 50, frame=k, state=RobotState.RUNNING, mode=ControlMode.POSITION, statement=k,
                           q=(0.1, 0.2, 0.3, 0.4, 0.5, 0.6), position=(0.4, 0.0, 0.3), rpy=(0.0, 3.1, 0.0))
    return encode_frame(frame)


def _stamp(payload: bytes, k: int) -> bytes:
    return TAG.pack(k, time.perf_counter()) + payload[TAG.size :]


async def measure(url: str, delay_s: float, seconds: float, bursts: int, burst_size: int) -> dict:
    """Telemetry RTTs and burst times through ``url`` (an echo, directly or via the link)."""
    rtts: list[float] = []
    burst_times: list[float] = []
    units = [encode_unit(1, i, [Drive(joint=1 + i % 6, target=i * 1e-4)], end=False) for i in range(burst_size)]
    async with connect(url + "/telemetry", compression=None, max_size=None) as tel, \
            connect(url + "/command", compression=None, max_size=None, max_queue=None) as cmd:

        async def telemetry_out() -> None:
            t0 = time.perf_counter()
            for k in range(int(seconds * 50)):
                await tel.send(_stamp(_frame_payload(k), k))
                await asyncio.sleep(max(0.0, t0 + (k + 1) / 50 - time.perf_counter()))

        async def telemetry_in(n: int) -> None:
            for _ in range(n):
                raw = await tel.recv()
                rtts.append(time.perf_counter() - TAG.unpack_from(raw)[1])

        async def burster() -> None:
            gap = seconds / (bursts + 1)
            for _ in range(bursts):
                await asyncio.sleep(gap)
                t0 = time.perf_counter()
                for i, u in enumerate(units):
                    await cmd.send(_stamp(u, i))
                for _ in range(burst_size):
                    await cmd.recv()
                burst_times.append(time.perf_counter() - t0)

        await asyncio.gather(telemetry_out(), telemetry_in(int(seconds * 50)), burster())
    rtt = np.array(rtts) - 2 * delay_s
    bt = np.array(burst_times) - 2 * delay_s
    return {
        "telemetry_rtt_ms": {"p50": float(np.percentile(rtt, 50) * 1e3), "p99": float(np.percentile(rtt, 99) * 1e3),
                             "max": float(rtt.max() * 1e3), "n": len(rtt)},
        "burst_ms": {"median": float(np.median(bt) * 1e3) if len(bt) else None, "n": len(bt)},
        "burst_statements_per_s": float(burst_size / np.median(bt)) if len(bt) else None,
    }


def start_link(port: int, robot_port: int, delay_ms: float, log_path: Path) -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-m", "server.cli", "link", "--port", str(port), "--robot", f"ws://127.0.0.1:{robot_port}",
         "--delay-ms", str(delay_ms)],
        cwd=ROOT, stdout=log_path.open("w"), stderr=subprocess.STDOUT, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    wait_http(f"http://127.0.0.1:{port}/health", proc, timeout=60)
    return proc


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=8.0, help="length of each run (s)")
    ap.add_argument("--bursts", type=int, default=3, help="bursts per run")
    ap.add_argument("--burst-size", type=int, default=1000, help="statements per burst")
    ap.add_argument("--delay-ms", type=float, default=3000.0, help="the set delay of the delayed run")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--echo-server", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.echo_server is not None:
        asyncio.run(run_echo_server(args.echo_server))
        return 0

    echo_port = free_port()
    echo = subprocess.Popen([sys.executable, __file__, "--echo-server", str(echo_port)], cwd=ROOT)
    procs = [echo]
    results: dict[str, dict] = {}
    try:
        time.sleep(1.0)
        d = args.delay_ms
        runs = [
            ("echo, 50 Hz only", None, 0.0, 0), (f"link {d:.0f} ms, 50 Hz only", d, d / 1e3, 0),
            ("echo", None, 0.0, args.bursts), ("link 0 ms", 0.0, 0.0, args.bursts),
            (f"link {d:.0f} ms", d, d / 1e3, args.bursts),
        ]
        for name, link_delay_ms, delay_s, bursts in runs:
            url = f"ws://127.0.0.1:{echo_port}"
            link = None
            if link_delay_ms is not None:
                port = free_port()
                link = start_link(port, echo_port, link_delay_ms, Path("/tmp") / f"bench-link-{port}.log")
                procs.append(link)
                url = f"ws://127.0.0.1:{port}"
            results[name] = asyncio.run(measure(url, delay_s, args.seconds, bursts, args.burst_size))
            if link is not None:
                import httpx

                health = httpx.get(url.replace("ws://", "http://") + "/health", timeout=10).json()
                results[name]["relay_lateness_ms"] = health["lateness_ms"]
                link.terminate()
                link.wait(timeout=15)
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
                p.wait(timeout=15)

    for name, r in results.items():
        base = results["echo, 50 Hz only" if "only" in name else "echo"]
        r["ratio_rtt_p50"] = base["telemetry_rtt_ms"]["p50"] / r["telemetry_rtt_ms"]["p50"]
        r["ratio_burst"] = base["burst_ms"]["median"] / r["burst_ms"]["median"] if r["burst_ms"]["n"] else None
    if args.json:
        print(json.dumps(results, indent=1))
        return 0
    print(f"{'set-up':<26} {'RTT p50':>9} {'RTT p99':>9} {'RTT max':>9} {'burst':>10} {'stmt/s':>9}  ratio (echo/link): RTT p50, burst")
    for name, r in results.items():
        t, b = r["telemetry_rtt_ms"], r["burst_ms"]
        burst = f"{b['median']:8.1f}ms {r['burst_statements_per_s']:9.0f}" if b["n"] else f"{'-':>10} {'-':>9}"
        ratio_burst = f"{r['ratio_burst']:.2f}x" if b["n"] else "-"
        print(f"{name:<26} {t['p50']:8.3f}ms {t['p99']:8.3f}ms {t['max']:8.3f}ms {burst}  {r['ratio_rtt_p50']:.2f}x, {ratio_burst}")
    print("(link rows: round trip minus 2 x the set delay)")
    for name, r in results.items():
        if "relay_lateness_ms" in r:
            late = r["relay_lateness_ms"]
            print(f"{name}: relay hands each message to its socket {late['p50']:.3f} ms (p50), {late['p99']:.3f} ms (p99), "
                  f"{late['max']:.3f} ms (max) after its due time, over {late['n']} deliveries")
    return 0


if __name__ == "__main__":
    sys.exit(main())
