"""Benchmark of the interpreter and trajectory planner (``shared.motion``).

Plans a 10,000-statement program for the PUMA 562 in the peg-in-hole cell (a repeated cycle of
MOVE, DRIVE, DRAW, ROTATE, MOVES, SPEED and EVENT statements), and reports:

* planning time per statement kind and in total, against the planned program's duration
  (how many times faster than real time the planner runs);
* a program of joint moves only (MOVE, DRIVE, SPEED; as many statements) against ruckig (PyPI ``ruckig``, the Ruckig online trajectory
  generator) computing the same rest-to-rest, phase-synchronised, acceleration-limited profiles
  (infinite jerk) with the same limits: time per move and agreement of the durations;
* sampling the whole plan at 100 Hz (what the preview and the executor do), against sampling
  ruckig's trajectories of the joint moves with ``Trajectory.at_time``.

    .venv/bin/python benchmarks/bench_motion.py                 # table
    .venv/bin/python benchmarks/bench_motion.py --json
    .venv/bin/python benchmarks/bench_motion.py --statements 2000
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from shared.cells.loader import load_cell  # noqa: E402
from shared.language.statements import Draw, Drive, Event, Move, Moves, Rotate, SetSpeed, Speed  # noqa: E402
from shared.motion import Interpreter, SegmentKind, plan_program  # noqa: E402
from shared.paths import ASSETS_DIR  # noqa: E402

CELL_PATH = ASSETS_DIR / "cells" / "peg_in_hole.toml"


def cycle(q_home: np.ndarray) -> list:
    """Ten statements that start and end at the cell's home pose (so the cycle can repeat)."""
    down = (math.pi, 0.0, 0.0)
    q_a = np.radians([10.0, -60.0, 190.0, 10.0, 40.0, 150.0])
    return [
        SetSpeed(speed=Speed(value=0.8, unit="fraction")),
        Move(joints=tuple(q_a)),
        Drive(joint=6, target=math.radians(120.0)),
        Move(joints=tuple(q_home)),
        Draw(position=(0.04, 0.0, 0.12), frame="WORK"),
        Draw(position=(0.04, 0.04, 0.12), frame="WORK", speed=Speed(value=0.05, unit="m/s")),
        Rotate(rpy=(math.pi, 0.0, math.radians(20.0)), frame="WORK"),
        Moves(position=(0.0, 0.0, 0.14), rpy=down, frame="WORK"),
        Event(name="lap"),
        Move(joints=tuple(q_home)),
    ]


def build_program(n: int, q_home: np.ndarray) -> list:
    one = cycle(q_home)
    return [one[i % len(one)] for i in range(n)]


def bench_planner(program: list, cell) -> dict:
    # whole program through plan_program (what `teleprog plan` does)
    t0 = time.perf_counter()
    plan = plan_program(program, cell.robot, cell)
    total = time.perf_counter() - t0
    if not plan.ok:
        raise SystemExit(f"benchmark program refused: {plan.refusal}")
    # per kind, statement by statement through the interpreter
    interp = Interpreter.for_cell(cell)
    per_kind: dict[str, list[float]] = defaultdict(list)
    for st in program:
        t = time.perf_counter()
        interp.plan_next(st)
        per_kind[st.kind].append(time.perf_counter() - t)
    return {
        "plan": plan,
        "plan_seconds": total,
        "program_seconds": plan.duration,
        "per_kind_us": {k: 1e6 * float(np.mean(v)) for k, v in sorted(per_kind.items())},
        "per_kind_count": {k: len(v) for k, v in sorted(per_kind.items())},
    }


def bench_sampling(plan, rate: float = 100.0) -> dict:
    """The whole plan at ``rate``: the first call (which builds the plan's sampling table) and
    the best of three further calls."""
    ts = np.arange(0.0, plan.duration, 1.0 / rate)
    t0 = time.perf_counter()
    samples = plan.sample(ts)
    first = time.perf_counter() - t0
    assert samples.q.shape == (ts.size, plan.q_start.size)
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        plan.sample(ts)
        best = min(best, time.perf_counter() - t0)
    return {"samples": int(ts.size), "first_seconds": first, "seconds": best, "per_sample_us": 1e6 * best / ts.size}


def joint_program(n: int, q_home: np.ndarray) -> list:
    """The joint statements of the cycle only (for the comparison with ruckig)."""
    one = [st for st in cycle(q_home) if st.kind in ("SPEED", "MOVE", "DRIVE")]
    return [one[i % len(one)] for i in range(n)]


def best_of(repeats: int, fn) -> float:
    """Smallest wall time of ``repeats`` runs of ``fn()`` (the machine is shared)."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def bench_ruckig(cell, n: int, rate: float = 100.0) -> dict | None:
    """Joint moves only: plan + sample at ``rate`` with shared.motion, and the same with ruckig."""
    try:
        from ruckig import InputParameter, Ruckig, Synchronization, Trajectory
    except ImportError:
        return None
    program = joint_program(n, cell.q_home)
    plan = plan_program(program, cell.robot, cell)
    moves = [s for s in plan.segments if s.kind is SegmentKind.JOINT and s.duration > 0]
    limits = Interpreter.for_cell(cell).limits
    dof = cell.robot.dof
    otg = Ruckig(dof)
    inp = InputParameter(dof)
    inp.max_acceleration = limits.joint_acceleration.tolist()
    inp.max_jerk = [math.inf] * dof  # acceleration-limited (trapezoidal) profiles, like ours
    inp.synchronization = Synchronization.Phase  # straight line in joint space, like ours
    inp.max_velocity = (limits.joint_velocity * 0.8).tolist()  # the cycle's SPEED 80 %
    trajectories: list = []

    def ruckig_plan() -> None:
        trajectories.clear()
        for seg in moves:
            inp.current_position = seg.q_start.tolist()
            inp.target_position = seg.q_end.tolist()
            traj = Trajectory(dof)
            otg.calculate(inp, traj)
            trajectories.append(traj)

    t_ours = best_of(3, lambda: plan_program(program, cell.robot, cell))
    t_ruckig = best_of(3, ruckig_plan)
    diff = max(abs(traj.duration - seg.duration) for seg, traj in zip(moves, trajectories))
    ts = np.arange(0.0, plan.duration, 1.0 / rate)
    t_ours_sample = best_of(3, lambda: plan.sample(ts))
    local = [np.arange(0.0, traj.duration, 1.0 / rate) for traj in trajectories]
    n_r = sum(x.size for x in local)

    def ruckig_sample() -> None:
        for traj, times in zip(trajectories, local):
            for t in times:
                traj.at_time(float(t))

    t_ruckig_sample = best_of(1, ruckig_sample)
    return {
        "moves": len(moves),
        "statements": len(program),
        "ours_us_per_move": 1e6 * t_ours / len(moves),
        "ruckig_us_per_move": 1e6 * t_ruckig / len(moves),
        "max_duration_difference_s": float(diff),
        "ours_sample_us": 1e6 * t_ours_sample / ts.size,
        "ruckig_sample_us": 1e6 * t_ruckig_sample / n_r,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--statements", type=int, default=10_000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    cell = load_cell(CELL_PATH)
    program = build_program(args.statements, cell.q_home)
    planner = bench_planner(program, cell)
    plan = planner.pop("plan")
    sampling = bench_sampling(plan)
    ruck = bench_ruckig(cell, args.statements)
    result = {
        "statements": len(program),
        "plan_seconds": planner["plan_seconds"],
        "program_seconds": planner["program_seconds"],
        "faster_than_real_time": planner["program_seconds"] / planner["plan_seconds"],
        "per_kind_us": planner["per_kind_us"],
        "per_kind_count": planner["per_kind_count"],
        "sampling_100hz": sampling,
        "ruckig": ruck,
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"program: {len(program)} statements, planned duration {result['program_seconds']:.1f} s")
    print(f"plan_program: {result['plan_seconds']:.2f} s  ->  {result['faster_than_real_time']:.0f}x faster than real time")
    for kind, us in result["per_kind_us"].items():
        print(f"  {kind:<7} {us:9.1f} us/statement  ({result['per_kind_count'][kind]})")
    s = sampling
    print(
        f"sampling at 100 Hz: {s['samples']} samples in {s['seconds'] * 1e3:.1f} ms ({s['per_sample_us']:.2f} us/sample; "
        f"first call with table build {s['first_seconds'] * 1e3:.0f} ms)"
    )
    if ruck is None:
        print("ruckig not installed: no comparison")
        return
    print(
        f"joint moves ({ruck['moves']}): ours {ruck['ours_us_per_move']:.1f} us/move (plan_program), "
        f"ruckig {ruck['ruckig_us_per_move']:.1f} us/move "
        f"(ratio ruckig/ours {ruck['ruckig_us_per_move'] / ruck['ours_us_per_move']:.2f}); "
        f"largest duration difference {ruck['max_duration_difference_s']:.2e} s"
    )
    print(
        f"sampling joint moves at 100 Hz: ours {ruck['ours_sample_us']:.3f} us/sample (Plan.sample), ruckig at_time "
        f"{ruck['ruckig_sample_us']:.2f} us/sample (ratio {ruck['ruckig_sample_us'] / ruck['ours_sample_us']:.1f})"
    )


if __name__ == "__main__":
    main()
