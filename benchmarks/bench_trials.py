"""Trials in virtual time: how long a batch of approach runs takes (issue 19's benchmark).

    .venv/bin/teleprog bench trials                    # 200 runs on 2 local processes, then on Dask
    .venv/bin/teleprog bench trials --runs 50 --no-dask --json

Each run is the approach trial at the thesis's 3 s delay (online, then step by step) with the
console's sender and planner, the link and the telerobot on one virtual clock
(``server.trials.virtual_clock``): about 45 s of session time, of which the telerobot moves for
about 8 s (800 servo steps of 10 ms, each a path sample, the contact model and a collision check
of the arm against the real cell). The same specs run on ``--workers`` local processes (forked
after the cell's models are built) and on a Dask ``LocalCluster`` with as many single-threaded
worker processes; the ratios are Dask's time over ours and real time (what the same runs take as
``teleprog up`` sessions, one after the other) over ours. Exit 1 when a run failed or the two
executors' tables differ.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

GOAL_S = 60.0  # issue 19: 200 virtual-time approach runs in under a minute on this machine


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--runs", type=int, default=200, help="approach runs (default 200)")
    p.add_argument("--workers", type=int, default=2, help="local processes, and Dask workers (default 2)")
    p.add_argument("--no-dask", action="store_true", help="skip the Dask LocalCluster run")
    p.add_argument("--json", action="store_true")


def _specs(runs: int):
    from server.trials.batch import RunSpec, TrialWorld, world_seed
    from server.trials.script import approach_script
    from shared.cells.loader import DEFAULT_CELL

    script = approach_script(DEFAULT_CELL)
    world = TrialWorld()
    return [RunSpec("approach", "both", i, world.settings(world_seed(0, i)), 3000.0, "virtual", "/tmp", script=script)
            for i in range(runs)], script


def _table(results, script) -> dict:
    from server.trials.results import summarize

    s = summarize(results, delay_ms=3000.0, seed=0, cell=script.cell, statements=len(script.statements), clock="virtual")
    return s.model_dump(exclude={"runs"})


def main_with(args: argparse.Namespace) -> int:
    import logging

    from tqdm import tqdm

    logging.getLogger("distributed").setLevel(logging.WARNING)

    from server.trials.batch import open_executor, run_all
    from server.trials.virtual_clock import warm

    specs, script = _specs(args.runs)
    warm(script.cell)
    out: dict = {"runs": args.runs, "workers": args.workers, "cpus": os.cpu_count(), "load_before": os.getloadavg()[0],
                 "goal_s": GOAL_S}
    bar = tqdm(total=args.runs, desc="local processes", unit="run", file=sys.stderr, disable=None, leave=False)
    t0 = time.perf_counter()
    with open_executor(args.workers) as executor:
        ours = run_all(specs, executor, on_done=lambda r: bar.update(1))
    out["local_s"] = time.perf_counter() - t0
    bar.close()
    session_s = [r.step_by_step.statements[-1].finished_at for r in ours if r.success]  # each run's clock at its end
    out["failed"] = sum(not r.success for r in ours)
    out["session_s_per_run"] = sum(session_s) / len(session_s) if session_s else None
    out["real_time_s"] = sum(session_s)
    out["ratio_real_time"] = out["real_time_s"] / out["local_s"]
    out["per_run_ms"] = 1e3 * out["local_s"] / args.runs
    ok = out["failed"] == 0
    if not args.no_dask:
        from distributed import LocalCluster

        bar = tqdm(total=args.runs, desc="dask LocalCluster", unit="run", file=sys.stderr, disable=None, leave=False)
        with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None,
                          host="127.0.0.1") as cluster:
            t0 = time.perf_counter()  # workers are up; like ours, their first run builds the cell's models
            with open_executor(scheduler=cluster.scheduler_address) as executor:
                theirs = run_all(specs, executor, on_done=lambda r: bar.update(1))
            out["dask_s"] = time.perf_counter() - t0
        bar.close()
        out["ratio_dask"] = out["dask_s"] / out["local_s"]
        out["same_table"] = _table(ours, script) == _table(theirs, script)
        ok = ok and out["same_table"]
    out["table"] = _table(ours, script)
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"{args.runs} virtual-time approach runs (3 s delay) on {args.workers} local processes: "
              f"{out['local_s']:.1f} s ({out['per_run_ms']:.0f} ms a run; goal {GOAL_S:g} s), load {out['load_before']:.2f}")
        print(f"  session time simulated: {out['real_time_s']:.0f} s ({out['session_s_per_run']:.1f} s a run): "
              f"{out['ratio_real_time']:.0f}x real time")
        if "dask_s" in out:
            print(f"  the same on a Dask LocalCluster ({args.workers} workers): {out['dask_s']:.1f} s, "
                  f"ratio {out['ratio_dask']:.2f}; same table: {out['same_table']}")
        t = out["table"]
        print(f"  online {t['online_total_s']} s, step by step {t['step_by_step_total_s']} s, ratio {t['ratio']}")
    return 0 if ok else 1


def main(argv=None, prog: str | None = None) -> int:
    p = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    add_arguments(p)
    return main_with(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
