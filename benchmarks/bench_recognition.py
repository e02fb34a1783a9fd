"""Task recognition while driving: the per-sample cost of the task coordinator against the
console's own collision check on the same drag (issue 18's benchmark).

    .venv/bin/teleprog bench recognition            # table
    .venv/bin/teleprog bench recognition --json
    .venv/bin/python benchmarks/bench_recognition.py --repeat 5

The samples are what the virtual cell goes through when the shipped peg transfer
(``assets/programs/peg_transfer.tp``) is played on ``assets/cells/peg_in_hole.toml`` with the
console's interpreter and planner, sampled every 0.01 s of program time, exactly as
``teleprog net recognise`` plays it (``shared.tasknet.playback``: the same loop, the object world
changed by the task calls between samples); each sample keeps the joint vector, the tool pose,
the held object and the moved objects' poses, i.e. what the console has after each drag step.

* *recognition*: what ``TaskMonitor._observe_virtual`` does on every ``ArmChanged``: build the
  ``CellState`` (the cell's objects, the moved ones at their poses, the gripper closed while it
  holds) and call ``TaskCoordinator.observe(state, t)``; a fresh coordinator from the cell as
  loaded, the samples in order, so the actions fire where they would.
* *full evaluation*: the same states with every atom of the task space decided
  (``ContactModel.evaluate(state)``), i.e. recognition without the context restriction of
  §3.5.3 (only the atoms the enabled transitions change are asked for).
* *collision check*: what ``VirtualArm.refresh`` calls after every change of the virtual arm,
  ``CellCollision.check(q, object_poses=..., held=..., data=...)`` with the arm's own scene
  data (its coherence carried from sample to sample), on the same samples.

Atoms and face pairs per sample are counted in a separate, untimed pass (``ContactModel``'s
``pairs_checked`` counter and the atoms each ``evaluate`` call is asked for). Each repeat runs
the three passes in turn; per-sample times of all repeats are pooled for median and p99, and
each sample's best of the repeats gives a second median and p99, less moved by other jobs
(``--check-samples N`` runs the last two on the first N samples only, for a quick run). Exit 1
when the sequence recognised is empty or differs from ``recognise_program``'s (or, for the
shipped program and cell, from grasp, part, mate, release).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

DEFAULT_PROGRAM = ROOT / "assets" / "programs" / "peg_transfer.tp"
DEFAULT_CELL = ROOT / "assets" / "cells" / "peg_in_hole.toml"
EXPECTED = ("grasp(PEG)", "part(PEG,HOLE1)", "mate(PEG,HOLE2)", "release(PEG)")
"""What ``teleprog net recognise`` prints for the shipped program and cell."""
FRAME_60HZ_US = 1e6 / 60.0
DRAG_RATE_HZ = (20.0, 60.0)
"""The gizmo's drag rate (events per second) the console has to keep up with."""


@dataclass(frozen=True)
class Sample:
    """One state of the virtual cell along the play, as the console holds it after a drag step."""

    t: float
    q: np.ndarray
    world_T_tcp: np.ndarray  # the tool as the object world has it (the state's tool pose)
    arm_T_tcp: np.ndarray  # the arm's own tool pose (the collision check's object poses ride on it)
    held: str | None
    moved: dict[str, np.ndarray]  # objects moved from their cell pose, the held one in the gripper


def play_samples(program, cell) -> tuple[list[Sample], object]:
    """The samples of ``shared.tasknet.playback.recognise_program``'s play (its own ``play``:
    same segments, same 0.01 s step, same task steps, the object world changed where it changes it)."""
    from shared.cells.object_world import ObjectWorld
    from shared.motion import plan_program
    from shared.motion.frames import CellFrames
    from shared.tasknet.playback import play

    robot = cell.robot
    plan = plan_program(program, robot, cell, None)
    frames = CellFrames.from_cell(cell)
    world = ObjectWorld(cell)
    out: list[Sample] = []
    for q, t, _ in play(plan, cell, world):
        arm = np.asarray(frames.world_T_tcp(robot, q), dtype=float)
        out.append(Sample(t, np.array(q, dtype=float), np.array(world.tool_pose(arm), dtype=float), arm, world.held,
                          {k: np.array(v, dtype=float) for k, v in world.poses(arm).items()}))
    return out, plan


def console_state(cell_objects: dict[str, np.ndarray], s: Sample):
    """``TaskMonitor._state`` for the virtual arm: the cell's objects, the moved ones where they are."""
    from shared.tasknet.contacts import CellState

    objects = dict(cell_objects)
    objects.update({k: np.asarray(v, dtype=float) for k, v in s.moved.items()})
    return CellState(np.asarray(s.world_T_tcp, dtype=float), s.held is not None, objects)


def stats_us(ns: list[int] | np.ndarray) -> dict[str, float]:
    a = np.asarray(ns, dtype=float) / 1e3
    return {"median": float(np.median(a)), "p99": float(np.percentile(a, 99)), "mean": float(a.mean()),
            "max": float(a.max()), "n": int(a.size)}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--program", default=str(DEFAULT_PROGRAM), help="program to play (default the shipped peg transfer)")
    p.add_argument("--cell", default=str(DEFAULT_CELL), help="cell file (default assets/cells/peg_in_hole.toml)")
    p.add_argument("--task", help="task space file (default assets/tasks/<cell>.toml)")
    p.add_argument("--repeat", type=int, default=3, help="timed passes over the samples (default 3)")
    p.add_argument("--check-samples", type=int, default=0, metavar="N",
                   help="run the full evaluation and the collision check on the first N samples only "
                        "(default 0: all; recognition always sees them all)")
    p.add_argument("--json", action="store_true")


def main_with(args: argparse.Namespace) -> int:
    from shared.cells.loader import load_cell
    from shared.cells.object_world import ObjectWorld
    from shared.collision.cell_check import CellCollision
    from shared.errors import InputError
    from shared.language.parser import parse_file
    from shared.tasknet.contacts import CellState, ContactModel
    from shared.tasknet.coordinator import TaskCoordinator
    from shared.tasknet.playback import recognise_program
    from shared.tasknet.taskspace import load_task_space, task_file_for_cell
    from shared.terrain.ground import GroundChecker

    if args.repeat < 1:
        raise InputError("--repeat must be at least 1")
    if args.check_samples < 0:
        raise InputError("--check-samples must be 0 (all) or more")
    cell = load_cell(args.cell)
    task_file = args.task or task_file_for_cell(cell.name)
    if task_file is None:
        raise InputError(f"cell {cell.name!r} has no task file; name one with --task")
    space = load_task_space(task_file)
    parsed = parse_file(args.program)
    if not parsed.ok:
        raise InputError(f"{args.program}: " + "; ".join(parsed.error_lines()))

    t0 = time.perf_counter()
    samples, plan = play_samples(parsed.statements, cell)
    reference = recognise_program(parsed.statements, cell, space)
    print(f"played {args.program}: {len(samples)} samples over {plan.duration:.2f} s of program time "
          f"({time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    if not samples:
        print("bench_recognition: the program moves nothing: no sample to recognise from", file=sys.stderr)
        return 1
    if plan.refusal is not None:
        print(f"bench_recognition: the planner refused part of the program: {plan.refusal}", file=sys.stderr)
        return 1

    cell_objects = {o.name: np.asarray(o.world_T_object, dtype=float) for o in cell.objects}
    start = CellState.of_world(ObjectWorld(cell), _home_tcp(cell))  # as TaskMonitor starts its coordinators
    expected = [a.action for a in reference.actions]
    shipped = (Path(args.program).resolve() == DEFAULT_PROGRAM.resolve()
               and Path(args.cell).resolve() == DEFAULT_CELL.resolve() and args.task is None)

    def wrong(actions: list[str], which: str) -> bool:
        """Say loudly (stderr) why ``actions`` cannot be measured; True when so."""
        problems = []
        if not actions:
            problems.append(f"no action was recognised from the samples ({which}): the benchmark would measure nothing")
        elif actions != expected:
            problems.append(f"{which} recognised {actions}, recognise_program gives {expected}")
        if shipped and actions and tuple(actions) != EXPECTED:
            problems.append(f"the shipped peg transfer should give {list(EXPECTED)}, got {actions} ({which})")
        for p in problems:
            print(f"bench_recognition: {p}", file=sys.stderr)
        return bool(problems)

    # -- counting pass (untimed): atoms and face pairs each observe asks for ---------------------
    contacts = ContactModel(space, cell)
    coord = TaskCoordinator(space, contacts, start)
    evaluate = contacts.evaluate
    asked: list[set[str]] = []

    def counting(state, atoms=None):
        asked.append(set(space.atom_texts) if atoms is None else set(atoms))
        return evaluate(state, atoms)

    contacts.evaluate = counting  # this instance only, for this pass
    atoms_per, pairs_per, calls_per, full_pairs = [], [], [], []
    for s in samples:
        asked.clear()
        before = contacts.pairs_checked
        coord.observe(console_state(cell_objects, s), s.t)
        atoms_per.append(len(set().union(*asked)))
        calls_per.append(len(asked))
        pairs_per.append(contacts.pairs_checked - before)
    if wrong([a.action for a in coord.actions], "the counting pass"):
        return 1
    contacts.evaluate = evaluate
    checked = samples[:args.check_samples] if args.check_samples else samples
    for s in checked:
        before = contacts.pairs_checked
        contacts.forget()  # every pair of every atom, measured
        contacts.evaluate(console_state(cell_objects, s))
        full_pairs.append(contacts.pairs_checked - before)

    t0 = time.perf_counter()
    collision = CellCollision(cell, ground=GroundChecker.for_cell(cell))  # as the console's session builds it
    collision.check(samples[0].q, data=collision.new_data())  # compiled kernels loaded before timing
    print(f"collision scene built ({time.perf_counter() - t0:.1f} s)", file=sys.stderr)

    # -- timed passes -------------------------------------------------------------------------
    rec_ns: list[int] = []
    full_ns: list[int] = []
    col_ns: list[int] = []
    clock = time.perf_counter_ns
    for r in range(args.repeat):
        contacts = ContactModel(space, cell)
        coord = TaskCoordinator(space, contacts, start)
        for s in samples:  # what _observe_virtual does on each ArmChanged
            a = clock()
            coord.observe(console_state(cell_objects, s), s.t)
            rec_ns.append(clock() - a)
        actions = [x.action for x in coord.actions]
        if wrong(actions, f"timed pass {r + 1}"):
            return 1
        for s in checked:
            a = clock()
            contacts.evaluate(console_state(cell_objects, s))
            full_ns.append(clock() - a)
        data = collision.new_data()
        for s in checked:  # what VirtualArm.refresh does after each change of the arm
            a = clock()
            collision.check(s.q, object_poses=s.moved or None, held=s.held, data=data)
            col_ns.append(clock() - a)

    rec, full, col = stats_us(rec_ns), stats_us(full_ns), stats_us(col_ns)
    for st, ns, n in ((rec, rec_ns, len(samples)), (full, full_ns, len(checked)), (col, col_ns, len(checked))):
        best = np.asarray(ns, dtype=float).reshape(args.repeat, n).min(axis=0) / 1e3  # per sample, best of the repeats
        st["best_median"], st["best_p99"] = float(np.median(best)), float(np.percentile(best, 99))
    all_pairs = int(np.median(full_pairs))
    doc = {
        "program": str(args.program), "cell": cell.name, "task": space.spec.name,
        "samples": len(samples), "check_samples": len(checked), "program_s": float(plan.duration), "sample_dt_s": 0.01,
        "repeat": args.repeat,
        "actions": actions,
        "recognised": [{"action": a.action, "t_s": None if a.t is None else round(a.t, 3)} for a in coord.actions],
        "recognition_us": rec, "full_evaluation_us": full, "collision_check_us": col,
        "atoms_checked": {"median": float(np.median(atoms_per)), "mean": float(np.mean(atoms_per)),
                          "max": int(max(atoms_per)), "all": len(space.atoms)},
        "pairs_checked": {"median": float(np.median(pairs_per)), "mean": float(np.mean(pairs_per)),
                          "max": int(max(pairs_per)), "all": all_pairs},
        "samples_measured": int(sum(1 for n in pairs_per if n > 0)),
        "evaluate_calls": {"mean": float(np.mean(calls_per)), "max": int(max(calls_per))},
        "samples_with_no_query": int(sum(1 for n in calls_per if n == 0)),
        "ratio_recognition_collision": {"median": rec["median"] / col["median"], "p99": rec["p99"] / col["p99"]},
        "ratio_full_restricted": full["median"] / rec["median"],
        "recognition_rate_hz": {"median": 1e6 / rec["median"], "p99": 1e6 / rec["p99"]},
        "drag_rate_hz": list(DRAG_RATE_HZ),
        "frame_60hz_share": {"recognition_median": rec["median"] / FRAME_60HZ_US, "recognition_p99": rec["p99"] / FRAME_60HZ_US,
                             "both_median": (rec["median"] + col["median"]) / FRAME_60HZ_US,
                             "both_p99": (rec["p99"] + col["p99"]) / FRAME_60HZ_US},
        "load_average": list(os.getloadavg()),
    }
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"{doc['samples']} samples over {doc['program_s']:.2f} s of program time (every 10 ms), {args.repeat} passes; "
          f"recognised: {', '.join(actions)}"
          + (f"; full evaluation and collision check on the first {len(checked)}" if len(checked) < len(samples) else ""))
    print("| per sample | median | p99 | mean | max | best of repeats: median | p99 |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, st in (("recognition (state + observe)", rec), ("full evaluation (all atoms)", full),
                     ("collision check (CellCollision.check)", col)):
        print(f"| {name} | {st['median']:.0f} µs | {st['p99']:.0f} µs | {st['mean']:.0f} µs | {st['max']:.0f} µs | "
              f"{st['best_median']:.0f} µs | {st['best_p99']:.0f} µs |")
    a, p = doc["atoms_checked"], doc["pairs_checked"]
    print()
    print("| measure | figure |")
    print("|---|---|")
    print(f"| atoms checked per sample (distinct) | median {a['median']:.0f}, mean {a['mean']:.1f}, max {a['max']} of {a['all']} |")
    print(f"| face pairs checked per sample (all its evaluate calls) | median {p['median']:.0f}, mean {p['mean']:.1f}, "
          f"max {p['max']}; all atoms: {p['all']} |")
    print(f"| samples whose faces were measured (the rest kept the last truth: no face could have crossed the "
          f"tolerance) | {doc['samples_measured']} of {doc['samples']} |")
    c = doc["evaluate_calls"]
    print(f"| evaluate calls per observe | mean {c['mean']:.2f}, max {c['max']} (one more after each firing) |")
    r = doc["ratio_recognition_collision"]
    print(f"| recognition / collision check | {r['median']:.2f}x (median), {r['p99']:.2f}x (p99) |")
    print(f"| full evaluation / recognition | {doc['ratio_full_restricted']:.2f}x (median) |")
    hz = doc["recognition_rate_hz"]
    print(f"| rate recognition alone allows | {hz['median']:,.0f} Hz (median), {hz['p99']:,.0f} Hz (p99); drag 20-60 Hz |")
    f = doc["frame_60hz_share"]
    print(f"| share of a 60 Hz frame (16.7 ms) | recognition {100 * f['recognition_median']:.2f} % (p99 "
          f"{100 * f['recognition_p99']:.2f} %); with the collision check {100 * f['both_median']:.2f} % "
          f"(p99 {100 * f['both_p99']:.2f} %) |")
    return 0


def _home_tcp(cell) -> np.ndarray:
    """The tool at the cell's home pose: where the console's coordinators start (``TaskMonitor``)."""
    from shared.motion.frames import CellFrames

    return np.asarray(CellFrames.from_cell(cell).world_T_tcp(cell.robot, cell.q_home), dtype=float)


def main(argv=None, prog: str | None = None) -> int:
    p = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    add_arguments(p)
    return main_with(p.parse_args(argv))


if __name__ == "__main__":
    try:
        sys.exit(main())
    except Exception as exc:  # a TeleprogError from bad options: one line, as the CLI does
        from shared.errors import TeleprogError

        if not isinstance(exc, TeleprogError):
            raise
        print(f"bench_recognition: error: {exc}", file=sys.stderr)
        sys.exit(1)
