"""Fault campaign throughput: runs an hour with 1 and 2 local workers (process pool) and on a Dask
``LocalCluster`` with 1 and 2 workers, the same campaign each time, and the check that every
executor gives the same results.

Each worker builds the cell's models, the compiled physics model and the composite schedule once
(per process) and a group's fault-free twin once per group of ten runs; the ratio against one
worker is the scale-out.

    .venv/bin/python benchmarks/bench_fault_campaign.py --runs 100
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.trials.faults.campaign import CampaignRequest, run_campaign  # noqa: E402
from shared.cells.loader import DEFAULT_CELL  # noqa: E402


def _key(runs) -> list[tuple]:
    return [(r.seed, r.outcome, r.stop_s, tuple((s.status, s.robot_run_s) for s in r.statements)) for r in runs]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=100)
    p.add_argument("--seed", type=int, default=31)
    p.add_argument("--no-dask", action="store_true")
    args = p.parse_args()
    rows, reference = [], None
    cases: list[tuple[str, dict]] = [("1 local worker (this process)", {"workers": 1}), ("2 local workers", {"workers": 2})]
    cluster = None
    for label, extra in cases + ([("dask LocalCluster, 1 worker", {"dask": 1}), ("dask LocalCluster, 2 workers", {"dask": 2})]
                                 if not args.no_dask else []):
        if "dask" in extra:
            from distributed import LocalCluster

            cluster = LocalCluster(n_workers=extra["dask"], threads_per_worker=1, processes=True, dashboard_address=None)
            req = CampaignRequest(runs=args.runs, seed=args.seed, scheduler=cluster.scheduler_address)
        else:
            req = CampaignRequest(runs=args.runs, seed=args.seed, workers=extra["workers"])
        t0 = time.perf_counter()
        runs, _ = run_campaign(req, DEFAULT_CELL)
        wall = time.perf_counter() - t0
        if cluster is not None:
            cluster.close()
            cluster = None
        same = reference is None or _key(runs) == reference
        reference = reference or _key(runs)
        rows.append((label, wall, args.runs * 3600.0 / wall, same))
        print(f"{label}: {wall:.1f} s, {args.runs * 3600.0 / wall:.0f} runs an hour, same results: {same}", file=sys.stderr)
    base = rows[0][1]
    print("| executor | wall (s) | runs an hour | against 1 worker | same results |")
    print("|---|---|---|---|---|")
    for label, wall, rate, same in rows:
        print(f"| {label} | {wall:.1f} | {rate:.0f} | {base / wall:.2f}x | {'yes' if same else 'NO'} |")
    return 0 if all(r[3] for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
