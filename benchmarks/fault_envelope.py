"""The delay envelope: the same fault campaign across one-way delays from 0.8 s to 15 s (with
jitter, and a lossy link at one point), composite control against step by step.

For each delay and mode: the peg transfer's time in its fault-free runs (median, first submit to
the last final report at the console) and the share of faulted runs the robot caught or that did
no harm (caught + absorbed), with misses and false stops. Prints a Markdown table and writes the
plot ``envelope.png``.

    .venv/bin/python benchmarks/fault_envelope.py --runs 50 --workers 2 --out benchmarks/figures/faults
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.trials.faults.campaign import CampaignRequest, run_campaign  # noqa: E402
from server.trials.faults.plots import envelope_plot  # noqa: E402
from shared.cells.loader import DEFAULT_CELL  # noqa: E402

DELAYS_MS = (800.0, 3000.0, 8000.0, 15000.0)
JITTER = 0.1  # of the delay, drawn per message
LOSSY = (3000.0, 0.0005)  # one more point: this delay with this chance of losing a message


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=50)
    p.add_argument("--seed", type=int, default=900)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    points, rows = [], []
    started = time.perf_counter()
    cases = [(d, d * JITTER, 0.0) for d in DELAYS_MS] + [(LOSSY[0], LOSSY[0] * JITTER, LOSSY[1])]
    for mode in ("composite", "step"):
        for delay, jitter, drop in cases:
            req = CampaignRequest(runs=args.runs, seed=args.seed, delay_ms=delay, jitter_ms=jitter,
                                  drop_probability=drop, mode=mode, workers=args.workers)
            runs, wall = run_campaign(req, DEFAULT_CELL)
            clean = [r.program_s for r in runs if r.fault.kind == "none" and r.outcome == "clean" and r.program_s]
            faulted = [r for r in runs if r.fault.kind != "none"]
            ok = sum(r.outcome in ("caught", "absorbed") for r in faulted)
            missed = sum(r.outcome == "missed" for r in runs)
            false = sum(r.outcome == "false_stop" for r in runs)
            t = statistics.median(clean) if clean else float("nan")
            if drop == 0.0:
                points.append({"mode": mode, "delay_ms": delay, "time_s": t, "ok_rate": ok / max(1, len(faulted))})
            rows.append(f"| {mode} | {delay / 1e3:g} s | {jitter / 1e3:g} s | {drop:g} | {t:.1f} s ({len(clean)} runs) | "
                        f"{ok}/{len(faulted)} | {missed} | {false} | {wall:.0f} s |")
            print(rows[-1], file=sys.stderr)
    print("| mode | delay | jitter | loss | transfer, fault-free (median) | faulted runs caught or harmless | missed | false stops | wall |")
    print("|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print(f"\n{time.perf_counter() - started:.0f} s in all, {args.runs} runs a point, seed {args.seed}")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        print(f"wrote {envelope_plot(points, args.out / 'envelope.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
