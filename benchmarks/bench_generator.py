"""Automatic program generation benchmark: a 60 s operator stream at 100 Hz.

The stream is made by jogging the PUMA 562 (``shared.robots.jog``) through a repeated script of
tool strokes (lines with corners, rotations, stops) and joint sweeps (a reversal, a change of
joint without stopping), with sensor-level noise added (0.05 mm, 0.02 deg). It is built once,
untimed. Measured:

* ours: ``ProgramGenerator.feed`` over the whole stream, sample by sample, plus ``flush`` (the
  online segmentation *and* the statement matching), best of several runs; the figure is how
  many times faster than real time (stream duration / generation time);
* established library: offline change-point detection with ``ruptures`` on the same work, the
  velocity signal of the whole stream (the same windowed finite differences, scaled by the same
  thresholds): PELT with the l2 cost, binary segmentation with the l2 cost, and the C-backed
  kernel CPD with the linear kernel (the same least-squares criterion). Their penalty is tuned
  by this script to the value that recovers the true change points best, which is generous to
  them (ours runs with its defaults). The ratio is their time / our time.

Accuracy for both: change points found within +-0.1 s of a true one (precision and recall),
and for ours also the statements' kinds against the script's.

Run: .venv/bin/python benchmarks/bench_generator.py [--json] [--skip-pelt]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass

import numpy as np

from shared.program.generator import GeneratorSettings, JogMode, ProgramGenerator, RobotSample
from shared.robots.jog import JogFrames, jog_joint, jog_tool, world_T_tcp
from shared.robots.loader import load_robot
from shared.spatial import exp_so3, log_so3

RATE = 100.0
DURATION = 60.0
MARGIN = 0.10  # s: a detected change point within this of a true one counts as found

# one cycle of the operator script: (mode, what, seconds, (frame, constraint, motion, step per tick) | (joint, step))
MM, DEG = 0.001, math.radians(1.0)
CYCLE = [
    ("tool", "still", 0.5, None),
    ("tool", "DRAW", 1.0, ("world", "x", "translate", [0.4 * MM, 0, 0])),
    ("tool", "DRAW", 1.0, ("world", "y", "translate", [0, 0.4 * MM, 0])),
    ("tool", "still", 0.5, None),
    ("tool", "ROTATE", 1.0, ("tool", "z", "rotate", [0, 0, 0.3 * DEG])),
    ("tool", "still", 0.4, None),
    ("tool", "DRAW", 1.0, ("world", "x", "translate", [-0.4 * MM, 0, 0])),
    ("tool", "DRAW", 1.0, ("world", "y", "translate", [0, -0.4 * MM, 0])),
    ("tool", "ROTATE", 1.0, ("tool", "z", "rotate", [0, 0, -0.3 * DEG])),
    ("tool", "still", 0.5, None),
    ("joint", "still", 0.3, None),
    ("joint", "DRIVE", 1.0, (1, 0.2 * DEG)),
    ("joint", "DRIVE", 1.0, (1, -0.2 * DEG)),
    ("joint", "still", 0.4, None),
    ("joint", "DRIVE", 0.8, (4, 0.3 * DEG)),
    ("joint", "DRIVE", 0.8, (6, 0.3 * DEG)),
    ("joint", "still", 0.3, None),
    ("joint", "DRIVE", 0.8, (6, -0.3 * DEG)),
    ("joint", "DRIVE", 0.8, (4, -0.3 * DEG)),
    ("joint", "still", 0.4, None),
]


@dataclass
class Stream:
    samples: list[RobotSample]
    truth: np.ndarray  # sample indices where the velocity changes
    kinds: list[str]  # statements the script calls for


def build_stream(seed: int = 0) -> Stream:
    robot = load_robot("puma562")
    frames = JogFrames(np.eye(4), np.eye(4), np.eye(4))
    q = np.radians([0.0, -45.0, 180.0, 0.0, 45.0, 0.0])
    rng = np.random.default_rng(seed)
    n_total = int(DURATION * RATE)
    qs, poses, modes, truth, kinds = [], [], [], [], []
    previous = "still"
    while len(qs) < n_total:
        for mode, what, seconds, how in CYCLE:
            if len(qs) >= n_total:
                break
            if (what != "still" or previous != "still") and qs:
                truth.append(len(qs) - 1)
            if what != "still":
                kinds.append(what)
            for _ in range(int(round(seconds * RATE))):
                if what == "still":
                    pass
                elif mode == "tool":
                    frame, constraint, motion, step = how
                    r = jog_tool(robot, q, frames=frames, frame=frame, constraint=constraint, motion=motion, displacement=np.array(step))
                    if r.blocked:
                        raise RuntimeError(f"benchmark script blocked: {r.message}")
                    q = r.q
                else:
                    joint, step = how
                    q = jog_joint(robot, q, joint, step).q
                qs.append(q.copy())
                poses.append(world_T_tcp(robot, q, frames))
                modes.append(mode)
            previous = what
    qs_arr = np.array(qs[:n_total])
    noisy_q = qs_arr + rng.normal(0.0, 0.02 * DEG, qs_arr.shape)
    samples = []
    for i in range(n_total):
        pose = poses[i].copy()
        pose[:3, 3] += rng.normal(0.0, 0.05 * MM, 3)
        pose[:3, :3] = exp_so3(rng.normal(0.0, 0.02 * DEG, 3)) @ pose[:3, :3]
        samples.append(RobotSample(i / RATE, noisy_q[i], JogMode(modes[i]), base_T_tool=pose))
    truth_arr = np.array([t for t in truth if t < n_total - 1])
    return Stream(samples, truth_arr, kinds)


def precision_recall(found: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Each true change point matches at most one found one within MARGIN (in samples)."""
    m = MARGIN * RATE
    used = np.zeros(len(found), dtype=bool)
    hits = 0
    for t in truth:
        close = np.flatnonzero((np.abs(found - t) <= m) & ~used)
        if close.size:
            used[close[np.argmin(np.abs(found[close] - t))]] = True
            hits += 1
    precision = float(used.sum() / len(found)) if len(found) else 0.0
    return precision, float(hits / len(truth))


def run_ours(stream: Stream) -> tuple[ProgramGenerator, list]:
    gen = ProgramGenerator()
    out = []
    for s in stream.samples:
        out.extend(gen.feed(s))
    out.extend(gen.flush())
    return gen, out


def our_change_points(gen: ProgramGenerator) -> np.ndarray:
    """Start and end of every segment that became a statement, as sample indices (segments of
    jitter that gave no statement are not change points of the motion)."""
    points = set()
    for seg in gen.segments:
        if seg.statement is None:
            continue
        points.add(int(round(seg.t_start * RATE)))
        points.add(int(round(seg.t_end * RATE)))
    return np.array(sorted(points))


def velocity_signal(stream: Stream, settings: GeneratorSettings) -> np.ndarray:
    """The windowed velocity of every sample (joint, linear, angular), each part scaled by its
    departure threshold: the signal the offline detectors segment."""
    k = max(int(round(settings.velocity_window * RATE)), 1)
    q = np.stack([s.q for s in stream.samples])
    p = np.stack([s.base_T_tool[:3, 3] for s in stream.samples])
    r = np.stack([s.base_T_tool[:3, :3] for s in stream.samples])
    dt = k / RATE
    vq = np.zeros_like(q)
    vq[k:] = (q[k:] - q[:-k]) / dt
    vp = np.zeros_like(p)
    vp[k:] = (p[k:] - p[:-k]) / dt
    w = np.zeros_like(p)
    rel = r[k:] @ np.transpose(r[:-k], (0, 2, 1))
    w[k:] = np.stack([log_so3(m) for m in rel]) / dt
    return np.concatenate(
        [vq / settings.joint_departure, vp / settings.linear_departure, w / settings.angular_departure], axis=1
    )


def timed(fn, repeat: int) -> tuple[float, object]:
    best, result = math.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result


def run_ruptures(signal: np.ndarray, truth: np.ndarray, skip_pelt: bool) -> list[dict]:
    import ruptures as rpt

    # the same work: a velocity change of the departure threshold (1 in scaled units) lasting
    # a few samples must be worth a break; tune the penalty for the best F1 (on the cheap
    # detector), then time every detector at that penalty
    min_size = 3
    kernel = rpt.KernelCPD(kernel="linear", min_size=min_size).fit(signal)
    best_pen, best_f1 = None, -1.0
    for pen in (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000):
        found = np.array(kernel.predict(pen=pen)[:-1]) - 1
        prec, rec = precision_recall(found, truth)
        f1 = 2 * prec * rec / (prec + rec) if prec + rec else 0.0
        if f1 > best_f1:
            best_pen, best_f1 = pen, f1
    rows = []
    detectors = [("ruptures KernelCPD linear (C)", lambda: rpt.KernelCPD(kernel="linear", min_size=min_size))]
    detectors.append(("ruptures Binseg l2", lambda: rpt.Binseg(model="l2", min_size=min_size, jump=1)))
    if not skip_pelt:
        detectors.append(("ruptures Pelt l2", lambda: rpt.Pelt(model="l2", min_size=min_size, jump=1)))
    for name, make in detectors:
        seconds, bkps = timed(lambda: make().fit(signal).predict(pen=best_pen), repeat=1)
        found = np.array(bkps[:-1]) - 1
        prec, rec = precision_recall(found, truth)
        rows.append({"name": name, "seconds": seconds, "penalty": best_pen, "change_points": len(found), "precision": prec, "recall": rec})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--json", action="store_true", help="print machine-readable figures")
    parser.add_argument("--repeat", type=int, default=5, help="runs of our generator (best is kept)")
    parser.add_argument("--skip-pelt", action="store_true", help="leave out ruptures' PELT (the slowest)")
    args = parser.parse_args()

    stream = build_stream()
    n = len(stream.samples)
    duration = n / RATE
    ours_s, (gen, statements) = timed(lambda: run_ours(stream), args.repeat)
    found = our_change_points(gen)
    prec, rec = precision_recall(found, stream.truth)
    kinds_ok = [s.kind for s in statements] == stream.kinds
    try:
        import ruptures as _ruptures  # the comparison needs it
        del _ruptures
    except ImportError:
        raise SystemExit("ruptures is needed for the comparison: .venv/bin/pip install ruptures") from None
    signal = velocity_signal(stream, gen.settings)
    signal_s, _ = timed(lambda: velocity_signal(stream, gen.settings), 1)
    theirs = run_ruptures(signal, stream.truth, args.skip_pelt)
    result = {
        "samples": n,
        "stream_seconds": duration,
        "true_change_points": int(len(stream.truth)),
        "ours": {
            "seconds": ours_s,
            "per_sample_us": ours_s / n * 1e6,
            "times_real_time": duration / ours_s,
            "statements": len(statements),
            "statements_expected": len(stream.kinds),
            "statement_kinds_match_script": kinds_ok,
            "change_points": int(len(found)),
            "precision": prec,
            "recall": rec,
        },
        "velocity_signal_seconds": signal_s,
        "ruptures": [dict(row, ratio=row["seconds"] / ours_s) for row in theirs],
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    o = result["ours"]
    print(f"stream: {n} samples, {duration:.0f} s at {RATE:.0f} Hz, {len(stream.truth)} true change points")
    print(f"{'method':34s} {'time':>9s} {'x real time':>12s} {'found':>6s} {'prec':>6s} {'recall':>7s}  ratio")
    print(f"{'ours: online generator (feed+flush)':34s} {o['seconds'] * 1e3:7.1f} ms {o['times_real_time']:11.0f}x {o['change_points']:6d} {o['precision']:6.2f} {o['recall']:7.2f}")
    for row in result["ruptures"]:
        print(f"{row['name']:34s} {row['seconds'] * 1e3:7.1f} ms {duration / row['seconds']:11.0f}x {row['change_points']:6d} {row['precision']:6.2f} {row['recall']:7.2f}  {row['ratio']:.1f}x")
    print(f"statements: {o['statements']} (script calls for {o['statements_expected']}; kinds match: {kinds_ok})")
    print(f"ruptures penalty {theirs[0]['penalty']}; their velocity signal took {signal_s * 1e3:.1f} ms more (not counted)")


if __name__ == "__main__":
    main()
