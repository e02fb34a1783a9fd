"""The telerobot's contact-physics world (MuJoCo): how fast it runs the peg transfer, what its
at-rest skipping saves, and what a batch of virtual-time trials costs with it.

    .venv/bin/python benchmarks/bench_physics.py               # table (about 3 min on 2 cores)
    .venv/bin/python benchmarks/bench_physics.py --quick       # 1 repeat, 1 trial run, 20 approach runs
    .venv/bin/python benchmarks/bench_physics.py --json

Measured, in one run:

* **Peg transfer, one process.** The 12 statements of ``transfer_program`` (approach .. release)
  for ``assets/cells/peg_in_hole.toml`` on ``PhysicsWorld`` (seed 0, 2 mm object offset) straight
  through the executor (``Executor.run_until_idle``), no console, no link: wall and simulated
  seconds, real-time factor (simulated / wall), MuJoCo steps per wall second, and the wall time
  split into ``mujoco.mj_step`` (a timing proxy in place of the world's ``mujoco`` module), the
  world's own Python around it (``servo``/``advance``: sensing, contact scans) and the rest
  (executor, controllers, planner, collision checks). The reference is the same statements on
  the kinematic world (``engine="kinematic"``), in the same run; ratio = physics wall /
  kinematic wall (above 1: physics is slower). Median of ``--repeats``, after one warm-up run of
  each (numba kernels, caches).
* **Time at rest.** ``PhysicsWorld.advance`` moves the clock on without stepping while the
  world is at rest, and MuJoCo's own sleeping (``PhysicsWorld.SLEEP``) stops integrating and
  colliding a body at rest (a peg in its hole) while the arm moves. Here both are switched off by
  a monkeypatch in this file (``_asleep`` forced False on entry to ``advance``, so every period is
  stepped, and ``SLEEP`` False for the worlds built meanwhile; ``RobotCore.skip_idle`` still skips
  the idle executor's ticks, and the world then steps the whole gap in one call), and the same
  work runs with and without: (a) the transfer statement by statement with ``--pause`` seconds of
  idle ticks after each (an operator thinking), comparing statuses, reasons and the final peg pose
  (to a micrometre); (b) ``--trial-runs`` insert trials (supervised, 3 s delay, virtual clock,
  ``server.trials.batch.run_spec``, what ``teleprog trial insert --clock virtual`` runs),
  comparing success, failure text and total times. Steps taken / skipped and wall time for each.
* **200 virtual-time approach runs.** ``teleprog trial approach --clock virtual --runs N --json``
  as a subprocess (start-up included), against issue 19's goal of 60 s.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

GOAL_S = 60.0  # issue 19: 200 virtual-time approach runs in under a minute
POSE_TOL_M = 1e-6  # a micrometre: the at-rest skip is outcome-neutral, not bit-identical (soft contacts creep)
PHASES = ("approach", "grasp", "extract", "carry", "insert", "release")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--repeats", type=int, default=3, help="timed transfers on each world (median; default 3)")
    p.add_argument("--pause", type=float, default=1.0, help="idle seconds after each statement in the skip check (default 1)")
    p.add_argument("--trial-runs", type=int, default=3, help="insert trials with and without skipping (default 3)")
    p.add_argument("--approach-runs", type=int, default=200, help="virtual-time approach runs (default 200)")
    p.add_argument("--workers", type=int, default=1, help="--workers for the approach runs (default 1, as the CLI)")
    p.add_argument("--approach-timeout", type=float, default=900.0, help="give the approach runs up after this (s)")
    p.add_argument("--no-approach", action="store_true", help="skip the approach runs")
    p.add_argument("--quick", action="store_true", help="1 repeat, 1 trial run, 20 approach runs")
    p.add_argument("--json", action="store_true")


# -- instruments ------------------------------------------------------------------------------
class _TimedMujoco:
    """The ``mujoco`` module with ``mj_step`` timed (set as a world's ``_mj``)."""

    def __init__(self, mujoco) -> None:
        self._m = mujoco
        self.step_s = 0.0
        self.calls = 0

    def __getattr__(self, name):
        return getattr(self._m, name)

    def mj_step(self, *args, **kwargs):
        t = time.perf_counter()
        try:
            return self._m.mj_step(*args, **kwargs)
        finally:
            self.step_s += time.perf_counter() - t
            self.calls += 1


def _instrument(world) -> dict:
    """Time ``mj_step`` and the world's servo/advance (outermost call only) on this instance."""
    timed = _TimedMujoco(world._mj)
    world._mj = timed
    acc = {"world_s": 0.0, "depth": 0, "mj": timed}

    def wrap(fn):
        def inner(*args, **kwargs):
            acc["depth"] += 1
            t = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                acc["depth"] -= 1
                if acc["depth"] == 0:
                    acc["world_s"] += time.perf_counter() - t
        return inner

    world.servo = wrap(world.servo)
    world.advance = wrap(world.advance)
    return acc


_COUNT = {"steps": 0, "skipped": 0}


@contextlib.contextmanager
def resting_skip(enabled: bool):
    """``PhysicsWorld`` as it is (``enabled``) or with both ways of letting time pass cheaply at
    rest off: the world's own at-rest skip and MuJoCo's sleeping of resting bodies (for worlds
    built meanwhile); counts the steps taken and skipped by every world in this process meanwhile
    (``_COUNT``)."""
    from robot_sim.physics.world import PhysicsWorld

    original, sleep = PhysicsWorld.advance, PhysicsWorld.SLEEP

    def advance(self, seconds, sense=True):
        steps, skipped = self.steps, self.skipped_steps
        if not enabled:
            self._asleep = False
        try:
            return original(self, seconds, sense)
        finally:
            _COUNT["steps"] += self.steps - steps
            _COUNT["skipped"] += self.skipped_steps - skipped

    PhysicsWorld.advance = advance
    PhysicsWorld.SLEEP = enabled
    _COUNT.update(steps=0, skipped=0)
    try:
        yield _COUNT
    finally:
        PhysicsWorld.advance, PhysicsWorld.SLEEP = original, sleep


# -- 1. the transfer, one process ----------------------------------------------------------------
def _cell():
    from shared.cells.loader import load_cell
    from shared.paths import ASSETS_DIR

    path = ASSETS_DIR / "cells" / "peg_in_hole.toml"
    return path, load_cell(path)


def _texts(path) -> list[str]:
    from server.trials.programs import transfer_program

    return transfer_program(path).texts(*PHASES)


def _executor(cell, engine: str):
    from robot_sim.executor import Executor
    from robot_sim.settings import WorldSettings
    from robot_sim.worlds import make_world

    return Executor(cell, make_world(cell, WorldSettings(engine=engine, seed=0, object_offset=0.002)))


def _finals(events) -> list[tuple[int, str, str | None]]:
    return [(e.number, e.state.value, e.reason) for e in events if e.state.value in ("done", "failed", "skipped", "aborted")]


def transfer_once(cell, texts, engine: str, instrument: bool = False) -> dict:
    from shared.language.parser import parse_statement

    ex = _executor(cell, engine)
    acc = _instrument(ex.world) if instrument else None
    for n, text in enumerate(texts, start=1):
        ex.enqueue(n, parse_statement(text))
    t0 = time.perf_counter()
    events = ex.run_until_idle(600.0)
    wall = time.perf_counter() - t0
    finals = _finals(events)
    out = {"wall_s": wall, "virtual_s": ex.time, "ok": len(finals) == len(texts) and all(s == "done" for _, s, _ in finals)}
    if engine != "kinematic":
        out["steps"] = ex.world.steps
        out["skipped_steps"] = ex.world.skipped_steps
    if acc is not None:
        out["mj_step_s"] = acc["mj"].step_s
        out["mj_step_calls"] = acc["mj"].calls
        out["world_python_s"] = acc["world_s"] - acc["mj"].step_s
        out["rest_s"] = wall - acc["world_s"]
    return out


def bench_transfer(cell, texts, repeats: int, bar) -> dict:
    transfer_once(cell, texts, "kinematic")  # warm-up: numba kernels, caches
    transfer_once(cell, texts, "physics")
    bar.update(2)
    phys, kin = [], []
    for _ in range(repeats):
        phys.append(transfer_once(cell, texts, "physics", instrument=True))
        kin.append(transfer_once(cell, texts, "kinematic"))
        bar.update(2)
    med = lambda rows, k: statistics.median(r[k] for r in rows)  # noqa: E731
    p = {k: med(phys, k) for k in ("wall_s", "virtual_s", "steps", "skipped_steps", "mj_step_s", "world_python_s", "rest_s", "mj_step_calls")}
    k = {key: med(kin, key) for key in ("wall_s", "virtual_s")}
    p["ok"] = all(r["ok"] for r in phys)
    k["ok"] = all(r["ok"] for r in kin)
    p["rtf"] = p["virtual_s"] / p["wall_s"]
    p["rtf_step_alone"] = p["virtual_s"] / p["mj_step_s"]
    p["steps_per_wall_s"] = p["steps"] / p["wall_s"]
    p["steps_per_step_s"] = p["steps"] / p["mj_step_s"]
    p["us_per_step"] = 1e6 * p["mj_step_s"] / p["steps"]
    k["rtf"] = k["virtual_s"] / k["wall_s"]
    return {"physics": p, "kinematic": k, "ratio_wall": p["wall_s"] / k["wall_s"], "repeats": repeats,
            "walls_physics": [r["wall_s"] for r in phys], "walls_kinematic": [r["wall_s"] for r in kin]}


# -- 2. at-rest skipping ---------------------------------------------------------------------------
def paused_transfer(cell, texts, pause: float) -> dict:
    """The transfer statement by statement, ``pause`` seconds of idle ticks after each."""
    from shared.language.parser import parse_statement

    ex = _executor(cell, "physics")
    events = []
    t0 = time.perf_counter()
    for n, text in enumerate(texts, start=1):
        ex.enqueue(n, parse_statement(text))
        events += ex.run_until_idle(600.0)
        for _ in range(int(round(pause / ex.dt))):
            events += ex.tick()
    wall = time.perf_counter() - t0
    peg = {name: p.world_T_peg.copy() for name, p in ex.world.pegs.items()}
    return {"wall_s": wall, "virtual_s": ex.time, "steps": ex.world.steps, "skipped_steps": ex.world.skipped_steps,
            "finals": _finals(events), "peg": peg}


def bench_skip(cell, path, texts, pause: float, trial_runs: int, bar) -> dict:
    from server.trials.batch import RunSpec, TrialWorld, run_spec, world_seed
    from server.trials.programs import transfer_program

    out: dict = {"pause_s": pause, "trial_runs": trial_runs}
    runs = {}
    for enabled in (True, False):
        with resting_skip(enabled):
            runs[enabled] = paused_transfer(cell, texts, pause)
        bar.update(1)
    on, off = runs[True], runs[False]
    pose_diff = max(float(np.max(np.abs(on["peg"][n][:3, 3] - off["peg"][n][:3, 3]))) for n in on["peg"])
    rot_diff = max(float(np.max(np.abs(on["peg"][n][:3, :3] - off["peg"][n][:3, :3]))) for n in on["peg"])
    out["transfer"] = {
        "skip": {k: on[k] for k in ("wall_s", "virtual_s", "steps", "skipped_steps")},
        "no_skip": {k: off[k] for k in ("wall_s", "virtual_s", "steps", "skipped_steps")},
        "same_statuses": on["finals"] == off["finals"],
        "peg_position_diff_m": pose_diff,
        "peg_rotation_diff": rot_diff,
        "same_pose": pose_diff <= POSE_TOL_M,
        "statuses_skip": on["finals"], "statuses_no_skip": off["finals"],
    }
    program = transfer_program(path)
    trials = {True: [], False: []}
    with tempfile.TemporaryDirectory() as log_dir:
        for i in range(trial_runs):
            spec = RunSpec("insert", "supervised", i, TrialWorld().settings(world_seed(0, i)), 3000.0, "virtual", log_dir,
                           program=program)
            for enabled in (True, False):
                with resting_skip(enabled) as count:
                    t0 = time.perf_counter()
                    r = run_spec(spec)
                    wall = time.perf_counter() - t0
                    trials[enabled].append({
                        "index": i, "wall_s": wall, "steps": count["steps"], "skipped_steps": count["skipped"],
                        "success": r.success, "failure": r.failure, "total_s": r.total_s, "robot_total_s": r.robot_total_s,
                        "statements": [(s.text, s.status, s.reason) for s in r.statements],
                    })
                bar.update(1)
    same = []
    for a, b in zip(trials[True], trials[False], strict=True):
        same.append({"index": a["index"], "same_outcome": (a["success"], a["failure"], a["statements"]) == (b["success"], b["failure"], b["statements"]),
                     "same_total_s": a["total_s"] == b["total_s"] and a["robot_total_s"] == b["robot_total_s"]})
    out["trials"] = {"skip": trials[True], "no_skip": trials[False], "compare": same,
                     "all_same_outcome": all(s["same_outcome"] for s in same),
                     "all_same_total_s": all(s["same_total_s"] for s in same)}
    return out


# -- 3. approach runs ------------------------------------------------------------------------------
def bench_approach(runs: int, workers: int, timeout: float) -> dict:
    exe = ROOT / ".venv" / "bin" / "teleprog"
    cmd = [str(exe), "trial", "approach", "--clock", "virtual", "--runs", str(runs), "--json"]
    if workers != 1:
        cmd += ["--workers", str(workers)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    except subprocess.TimeoutExpired:
        return {"runs": runs, "workers": workers, "wall_s": time.perf_counter() - t0, "timed_out": True, "command": " ".join(cmd[1:])}
    wall = time.perf_counter() - t0
    out = {"runs": runs, "workers": workers, "wall_s": wall, "per_run_ms": 1e3 * wall / runs, "rc": proc.returncode,
           "command": "teleprog " + " ".join(cmd[1:]), "goal_s": GOAL_S}
    try:
        s = json.loads(proc.stdout)["summary"]
        out.update(succeeded=s.get("runs_succeeded"), total=s.get("runs_total"),
                   online_total_s=s.get("online_total_s"), step_by_step_total_s=s.get("step_by_step_total_s"))
    except (ValueError, KeyError, TypeError):
        out["stderr_tail"] = proc.stderr[-500:]
    out["under_goal"] = wall < GOAL_S if runs == 200 else None
    out["projected_200_s"] = wall * 200 / runs
    return out


# -- report ----------------------------------------------------------------------------------------
def _f(x, d=2):
    return "–" if x is None else f"{x:.{d}f}"


def markdown(out: dict) -> str:
    rows = ["| measure | value |", "|---|---:|"]
    t = out.get("transfer")
    if t:
        p, k = t["physics"], t["kinematic"]
        rows += [
            f"| transfer on physics: wall (median of {t['repeats']}) | {p['wall_s']:.3f} s |",
            f"| transfer on physics: simulated | {p['virtual_s']:.2f} s |",
            f"| real-time factor, physics step and controllers together | {p['rtf']:.1f}x |",
            f"| real-time factor, physics step alone (`mj_step`) | {p['rtf_step_alone']:.1f}x |",
            f"| wall in `mj_step` / world's Python / executor and rest | {p['mj_step_s']:.3f} / {p['world_python_s']:.3f} / {p['rest_s']:.3f} s "
            f"({100 * p['mj_step_s'] / p['wall_s']:.0f} / {100 * p['world_python_s'] / p['wall_s']:.0f} / {100 * p['rest_s'] / p['wall_s']:.0f} %) |",
            f"| MuJoCo steps (skipped) | {p['steps']:.0f} ({p['skipped_steps']:.0f}) in {p['mj_step_calls']:.0f} `mj_step` calls |",
            f"| steps per wall second (all in) / in `mj_step` alone | {p['steps_per_wall_s']:,.0f} / {p['steps_per_step_s']:,.0f} ({p['us_per_step']:.1f} µs a step) |",
            f"| transfer on kinematic: wall / simulated | {k['wall_s']:.3f} s / {k['virtual_s']:.2f} s ({k['rtf']:.1f}x real time) |",
            f"| **ratio physics wall / kinematic wall** | **{t['ratio_wall']:.2f}x** |",
            f"| all statements done (physics / kinematic) | {p['ok']} / {k['ok']} |",
        ]
    s = out.get("skip")
    if s:
        a, b = s["transfer"]["skip"], s["transfer"]["no_skip"]
        rows += [
            f"| transfer, {s['pause_s']:g} s idle after each statement: steps, skip on | {a['steps']} taken, {a['skipped_steps']} skipped, {a['wall_s']:.2f} s wall |",
            f"| the same, skip off | {b['steps']} taken, {b['skipped_steps']} skipped, {b['wall_s']:.2f} s wall |",
            f"| same statuses and reasons / peg position diff | {s['transfer']['same_statuses']} / {s['transfer']['peg_position_diff_m']:.2e} m "
            f"({'within' if s['transfer']['same_pose'] else 'NOT within'} {POSE_TOL_M:g} m) |",
        ]
        for on, off, c in zip(s["trials"]["skip"], s["trials"]["no_skip"], s["trials"]["compare"], strict=True):
            rows.append(
                f"| insert trial {on['index']} (virtual clock), skip on / off: steps taken | {on['steps']} (+{on['skipped_steps']} skipped) / {off['steps']} "
                f"(+{off['skipped_steps']}); wall {on['wall_s']:.2f} / {off['wall_s']:.2f} s; total {_f(on['total_s'])} / {_f(off['total_s'])} s; "
                f"{'ok' if on['success'] else on['failure']} / {'ok' if off['success'] else off['failure']}; same outcome {c['same_outcome']}, same times {c['same_total_s']} |")
    ap = out.get("approach")
    if ap:
        if ap.get("timed_out"):
            rows.append(f"| {ap['runs']} approach runs (virtual clock) | gave up after {ap['wall_s']:.0f} s |")
        else:
            goal = "" if ap["runs"] != 200 else f" ({'under' if ap['under_goal'] else 'over'} the {GOAL_S:g} s goal)"
            rows.append(f"| {ap['runs']} approach runs, `{ap['command']}` | **{ap['wall_s']:.1f} s**{goal}, {ap['per_run_ms']:.0f} ms a run, "
                        f"{ap.get('succeeded')}/{ap.get('total')} succeeded; 200 would take ~{ap['projected_200_s']:.0f} s |")
    head = (f"Physics world benchmark (MuJoCo {out.get('mujoco')}), {out['cpus']} CPUs, load {out['load_before']:.2f} before, "
            f"{out['load_after']:.2f} after, {out['elapsed_s']:.0f} s in all\n")
    return head + "\n" + "\n".join(rows)


def main_with(args: argparse.Namespace) -> int:
    import logging

    import mujoco
    from tqdm import tqdm

    logging.disable(logging.WARNING)  # statements that fail log warnings; the table says what happened
    if args.quick:
        args.repeats, args.trial_runs, args.approach_runs = 1, 1, min(args.approach_runs, 20)
    t_start = time.perf_counter()
    out: dict = {"cpus": os.cpu_count(), "load_before": os.getloadavg()[0], "mujoco": mujoco.__version__}
    path, cell = _cell()
    texts = _texts(path)
    out["statements"] = texts
    bar = tqdm(total=2 + 2 * args.repeats + 2 + 2 * args.trial_runs, desc="physics", unit="run", file=sys.stderr,
               disable=None, leave=False)
    out["transfer"] = bench_transfer(cell, texts, args.repeats, bar)
    out["skip"] = bench_skip(cell, path, texts, args.pause, args.trial_runs, bar)
    bar.close()
    if not args.no_approach:
        print(f"{args.approach_runs} approach runs (subprocess) ...", file=sys.stderr)
        out["approach"] = bench_approach(args.approach_runs, args.workers, args.approach_timeout)
    out["load_after"] = os.getloadavg()[0]
    out["elapsed_s"] = time.perf_counter() - t_start
    ok = (out["transfer"]["physics"]["ok"] and out["skip"]["transfer"]["same_statuses"] and out["skip"]["transfer"]["same_pose"]
          and out["skip"]["trials"]["all_same_outcome"])
    out["ok"] = ok
    if args.json:
        print(json.dumps(out, indent=1, default=str))
    else:
        print(markdown(out))
    return 0 if ok else 1


def main(argv=None, prog: str | None = None) -> int:
    p = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    add_arguments(p)
    return main_with(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
