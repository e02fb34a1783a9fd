"""Merge fault campaigns (``teleprog trial faults --out DIR``) into one summary, its plot, and the
stopping table of the README's Safety section (each stop's cause, how far the tool still went,
how long until it rested), measured in the physics.

    .venv/bin/python benchmarks/fault_campaign_report.py /tmp/camp/s2026 /tmp/camp/s2027 ... \
        --out benchmarks/figures/faults

Prints Markdown: the campaign's table, then the stopping table.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.trials.faults.plots import outcome_plot  # noqa: E402
from server.trials.faults.results import FaultReport, FaultRun, summarize, table_lines  # noqa: E402

CAUSES = (  # (words in the reason, the stop's cause as the table names it)
    ("unplanned contact", "unplanned contact: force past 15 N in a position-mode motion, or an arm link touching"),
    ("over the safety limit", "force past the 80 N safety limit (guarded motion, task, gripper)"),
    ("does not follow", "following error: the flange 4 mm off the commanded pose"),
    ("on nothing", "grip: the fingers closed past the object (2 mm)"),
    ("lost from the gripper", "grip: the held object slipped out (2 mm)"),
    ("closed on", "grip: the fingers closed on the wrong object"),
    ("sensor", "wrist sensor readings invalid"),
    ("jammed", "jam: 0.5 s without progress under the seating push"),
    ("stuck", "stuck peg: extraction pull past 40 N"),
    ("no hole found", "hole not found within the 4 mm search"),
    ("pressing further", "recovery: a motion pressing further into a contact"),
    ("silence", "silence: nothing heard for 0.2 s + 1 s with work to do"),
    ("no message from the console", "silence: nothing heard for 0.2 s + 1 s with work to do"),
    ("unstable", "physics unstable (the world restored, the arm held)"),
)


def cause_of(run: FaultRun) -> str:
    reasons = [run.robot_reason or ""] + [s.reason or "" for s in run.statements if s.status == "failed"] + run.halts
    text = " ".join(reasons).lower()
    for words, cause in CAUSES:
        if words in text:
            return cause
    return "other: " + (reasons[0][:60] if reasons else "a stop with no report yet")


def stopping_table(runs: list[FaultRun]) -> list[str]:
    by: dict[str, list[FaultRun]] = defaultdict(list)
    for r in runs:
        if r.stop_s is not None and r.stop_distance_mm is not None:
            by[cause_of(r)].append(r)
    out = ["| the stop's cause | stops | tool travel after the stop p50 / p99 / max (mm) | to rest p50 / max (ms) |",
           "|---|---|---|---|"]
    for cause, rs in sorted(by.items(), key=lambda kv: -len(kv[1])):
        d = np.array([r.stop_distance_mm for r in rs])
        t = np.array([r.stop_time_ms for r in rs if r.stop_time_ms is not None])
        rest = f"{np.percentile(t, 50):.0f} / {t.max():.0f}" if t.size else "-"
        out.append(f"| {cause} | {len(rs)} | {np.percentile(d, 50):.2f} / {np.percentile(d, 99):.2f} / {d.max():.2f} | {rest} |")
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dirs", nargs="+", type=Path)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    reports = [FaultReport.model_validate_json((d / "results.json").read_text()) for d in args.dirs]
    runs = [r for rep in reports for r in rep.runs]
    first = reports[0].summary
    seeds = sorted({rep.summary.seed for rep in reports})
    wall = sum(rep.summary.wall_s or 0.0 for rep in reports)
    summary = summarize(runs, seed=seeds[0], delay_ms=first.delay_ms, jitter_ms=first.jitter_ms,
                        drop_probability=first.drop_probability, program=first.program, mode=first.mode,
                        world=first.world, wall_s=wall)
    lines = table_lines(summary)
    lines[0] += f" (seeds {seeds[0]}-{seeds[-1]})" if len(seeds) > 1 else ""
    print("\n".join(lines))
    print()
    print("\n".join(stopping_table(runs)))
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        outcome_plot(summary, args.out / "outcomes.png")
        (args.out / "summary.json").write_text(summary.model_dump_json(indent=1))
        print(f"\nwrote {args.out / 'outcomes.png'}, {args.out / 'summary.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
