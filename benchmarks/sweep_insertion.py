"""Insertion success on contact physics against the lateral offset and the grasp tilt.

Each point is ``--runs`` virtual-time runs of the insert trial (``teleprog trial insert --clock
virtual``: the untimed setup approaches, grasps, extracts and carries the peg, then the robot's
insertion task runs under supervision over the 3 s link), each run a fresh seeded world. The
success rate is what the contact made happen; nothing sets a chance. Every point carries its
Wilson 95 % interval and the failures' causes, counted from the robot's reasons:

* ``jammed``: the seating push made no progress (wedged or stuck on a wall);
* ``no hole found``: the spiral search passed its radius without the peg dropping in;
* ``peg lost``: the fingers lost the peg;
* ``force limit``: a contact force passed the safety limit;
* ``setup``: the run never reached the insertion (the extraction stuck, say);
* ``other``: anything else (named in the JSON).

Usage::

    .venv/bin/python benchmarks/sweep_insertion.py --runs 20 --workers 2 \\
        --out benchmarks/figures/insertion_sweep.png --json benchmarks/figures/insertion_sweep.json
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from server.trials.batch import RunSpec, TrialWorld, run_spec, world_seed  # noqa: E402
from server.trials.programs import transfer_program  # noqa: E402
from server.trials.stats import wilson_interval  # noqa: E402
from shared.paths import DEFAULT_CELL  # noqa: E402

CAUSES = ("jammed", "no hole found", "peg lost", "force limit", "setup", "other")


def cause(failure: str | None, reached: bool) -> str:
    text = failure or ""
    if not reached or text.startswith("setup: "):
        return "setup"
    if "jammed" in text:
        return "jammed"
    if "no hole found" in text:
        return "no hole found"
    if "lost from the gripper" in text:
        return "peg lost"
    if "over the safety limit" in text or "unplanned contact" in text:
        return "force limit"
    return "other"


def _one(args: tuple[dict, int, int]) -> tuple[bool, str, str]:
    world, seed, index = args
    logging.disable(logging.WARNING)
    program = transfer_program(str(DEFAULT_CELL))
    spec = RunSpec("insert", "supervised", index, TrialWorld(**world).settings(world_seed(seed, index)), 3000.0,
                   "virtual", "/tmp/teleprog-sweep", program=program)
    run = run_spec(spec)
    return bool(run.success), ("" if run.success else cause(run.failure, run.reached)), run.failure or ""


def sweep(name: str, values: list[float], base: dict, runs: int, seed: int, pool) -> list[dict]:
    points = []
    for value in values:
        world = {**base, name: value}
        t0 = time.monotonic()
        results = list(pool.map(_one, [(world, seed, i) for i in range(runs)]))
        ok = sum(r[0] for r in results)
        reached = sum(r[1] != "setup" for r in results)
        lo, hi = wilson_interval(ok, reached) if reached else (0.0, 1.0)
        counts = {c: sum(r[1] == c for r in results) for c in CAUSES}
        others = sorted({r[2] for r in results if r[1] == "other"})
        points.append({name: value, "runs": runs, "reached": reached, "succeeded": ok,
                       "success": ok / reached if reached else None, "wilson95": [lo, hi],
                       "causes": counts, "other_reasons": others, "wall_s": round(time.monotonic() - t0, 1)})
        print(f"{name} = {value:g}: {ok}/{reached} ({100 * ok / max(reached, 1):.0f} %, Wilson {100 * lo:.0f}-"
              f"{100 * hi:.0f} %), causes {counts}", flush=True)
    return points


def plot(result: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, (key, label, unit) in zip(axes, (("object_offset_mm", "lateral offset of the plate, up to", "mm"),
                                             ("grasp_tilt_deg", "peg's tilt in the fingers", "deg")), strict=True):
        pts = result[key]
        x = [p[key] for p in pts]
        y = [100 * (p["success"] or 0.0) for p in pts]
        lo = [max(0.0, y_ - 100 * p["wilson95"][0]) for y_, p in zip(y, pts, strict=True)]
        hi = [max(0.0, 100 * p["wilson95"][1] - y_) for y_, p in zip(y, pts, strict=True)]
        ax.errorbar(x, y, yerr=[lo, hi], fmt="o-", capsize=4, color="tab:blue", label="success (Wilson 95 %)")
        bottom = [0.0] * len(pts)
        colours = {"jammed": "tab:red", "no hole found": "tab:orange", "peg lost": "tab:purple",
                   "force limit": "tab:brown", "setup": "tab:gray", "other": "black"}
        width = (max(x) - min(x)) / (len(x) * 3) if len(x) > 1 else 0.2
        for c in CAUSES:
            share = [100 * p["causes"][c] / p["runs"] for p in pts]
            if any(share):
                ax.bar(x, share, width=width, bottom=bottom, color=colours[c], alpha=0.45, label=f"failed: {c}")
                bottom = [b + s for b, s in zip(bottom, share, strict=True)]
        ax.axhline(90, color="green", linestyle=":", label="thesis: 90 %")
        ax.set_xlabel(f"{label} ({unit})")
        ax.set_ylabel("runs (%)")
        ax.set_ylim(0, 105)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(f"Insertion on MuJoCo contact physics: {result['runs']} runs a point, seed {result['seed']}")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--offsets", default="0,1,2,3,4,5,6", help="offsets to sweep, mm (the tilt sweep uses 2 mm)")
    p.add_argument("--tilts", default="0,0.25,0.5,1,1.5,2", help="grasp tilts to sweep, deg (at 2 mm offset)")
    p.add_argument("--out", default="benchmarks/figures/insertion_sweep.png")
    p.add_argument("--json", default="benchmarks/figures/insertion_sweep.json")
    p.add_argument("--replot", action="store_true", help="draw the plot from --json without running")
    args = p.parse_args()
    if args.replot:
        plot(json.loads(Path(args.json).read_text()), Path(args.out))
        print(f"wrote {args.out}")
        return 0
    t0 = time.monotonic()
    result: dict = {"runs": args.runs, "seed": args.seed, "engine": "mujoco", "delay_ms": 3000.0}
    with ProcessPoolExecutor(args.workers) as pool:
        result["object_offset_mm"] = sweep("object_offset_mm", [float(v) for v in args.offsets.split(",")],
                                           {}, args.runs, args.seed, pool)
        result["grasp_tilt_deg"] = sweep("grasp_tilt_deg", [float(v) for v in args.tilts.split(",")],
                                         {"object_offset_mm": 2.0}, args.runs, args.seed, pool)
    result["wall_s"] = round(time.monotonic() - t0, 1)
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(result, indent=1))
    plot(result, Path(args.out))
    print(f"wrote {args.out} and {args.json} in {result['wall_s']} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
