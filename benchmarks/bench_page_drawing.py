"""What the console's page costs to draw where WebGL runs in software (headless Chromium with
SwiftShader; a laptop without a GPU): the CPU its processes use while the page sits open and idle
(viser redraws the scene once a second as a safety net) and while the arm is jogged through the API.

    .venv/bin/python benchmarks/bench_page_drawing.py                  # starts its own console
    .venv/bin/python benchmarks/bench_page_drawing.py --url http://127.0.0.1:8080 --dpr 1 0.5

Each configuration opens a fresh page (1400 x 900, the tests' size) at the console, waits for
its first frames, then measures Chromium's processes (GPU process, renderer, the rest) over
``--seconds`` idle and over ``--seconds`` of jogs (one small joint jog every 100 ms). Figures are
CPU seconds per wall second (1.0 = one core). Nothing here is a test: the machine's other work
shows in the figures, so compare configurations measured in the same minutes.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from support import CHROMIUM_ARGS, free_port  # noqa: E402


def chromium_cpu() -> dict[str, float]:
    """CPU seconds so far of every Chromium process, by its --type (the browser has none)."""
    out: dict[str, float] = {}
    for proc in psutil.process_iter(["cmdline"]):
        try:
            line = " ".join(proc.info["cmdline"] or [])
            if "chromium" not in line:
                continue
            kind = line.split("--type=")[1].split()[0] if "--type=" in line else "browser"
            times = proc.cpu_times()
            out[kind] = out.get(kind, 0.0) + times.user + times.system
        except (psutil.NoSuchProcess, psutil.AccessDenied, IndexError):
            continue
    return out


def rate(before: dict[str, float], after: dict[str, float], seconds: float) -> dict[str, float]:
    kinds = set(before) | set(after)
    gpu = (after.get("gpu-process", 0.0) - before.get("gpu-process", 0.0)) / seconds
    renderer = (after.get("renderer", 0.0) - before.get("renderer", 0.0)) / seconds
    total = sum(after.get(k, 0.0) - before.get(k, 0.0) for k in kinds) / seconds
    return {"gpu_process": round(gpu, 3), "renderer": round(renderer, 3), "all_chromium": round(total, 3)}


def call(url: str, method: str, path: str, body: dict | None = None) -> dict:
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(url + path, data=data, method=method, headers={"content-type": "application/json"})
    with urllib.request.urlopen(request, timeout=30) as reply:
        return json.loads(reply.read() or b"null")


def measure(browser, url: str, dpr: str, seconds: float) -> dict:
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    page = context.new_page()
    page.goto(f"{url}/viser/?fixedDpr={dpr}")
    page.wait_for_selector("canvas", timeout=120_000)
    page.get_by_role("button", name="STOP").wait_for(timeout=120_000)
    time.sleep(5.0)  # the first frames and the scene's meshes
    before, t0 = chromium_cpu(), time.monotonic()
    time.sleep(seconds)
    idle = rate(before, chromium_cpu(), time.monotonic() - t0)
    before, t0, sign = chromium_cpu(), time.monotonic(), 1.0
    while time.monotonic() - t0 < seconds:
        call(url, "POST", "/api/jog/joint", {"joint": 1, "delta_deg": 0.5 * sign})
        sign = -sign
        time.sleep(0.1)
    jogging = rate(before, chromium_cpu(), time.monotonic() - t0)
    context.close()
    return {"dpr": dpr, "idle": idle, "jogging": jogging}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", help="a running console (default: start `teleprog up --no-robot` for the run)")
    parser.add_argument("--dpr", nargs="+", default=["1", "0.5"], help="viser's fixedDpr values to measure")
    parser.add_argument("--seconds", type=float, default=10.0, help="length of each measurement, s")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    console = None
    url = args.url
    if url is None:
        port = free_port()
        console = subprocess.Popen([sys.executable, "-m", "server.cli", "up", "--no-robot", "--no-record", "--port", str(port)],
                                   cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        url = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 120
        while True:
            try:
                urllib.request.urlopen(url + "/api/health", timeout=2)
                break
            except OSError:
                if time.monotonic() > deadline or console.poll() is not None:
                    print("bench_page_drawing: the console did not start", file=sys.stderr)
                    return 1
                time.sleep(0.2)
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=os.environ.get("CHROMIUM", "/usr/bin/chromium"),
                                        headless=True, args=CHROMIUM_ARGS)
            rows = [measure(browser, url, dpr, args.seconds) for dpr in args.dpr]
            browser.close()
    finally:
        if console is not None:
            console.terminate()
            console.wait(timeout=30)
    load = os.getloadavg()[0]
    if args.json:
        print(json.dumps({"load": load, "rows": rows}, indent=2))
    else:
        print(f"load {load:.1f}; CPU s per s (1.0 = one core): GPU process / renderer / all Chromium")
        for row in rows:
            print(f"fixedDpr {row['dpr']:>4}: idle {row['idle']['gpu_process']:.2f} / {row['idle']['renderer']:.2f} / "
                  f"{row['idle']['all_chromium']:.2f}   jogging {row['jogging']['gpu_process']:.2f} / "
                  f"{row['jogging']['renderer']:.2f} / {row['jogging']['all_chromium']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
