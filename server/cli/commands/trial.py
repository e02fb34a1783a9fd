"""``teleprog trial KIND``: the thesis's trials (§4.6) as headless, repeatable experiments, each
run a whole real session (``teleprog up``: telerobot, delayed link, console) driven through the
console's HTTP API.

``teleprog trial approach`` runs the approach trial: the operator's approach to the peg as 4
statements of about 1 s, sent online (each as the virtual robot finishes it) and step by step
(each after the previous one's final report), and prints the measured totals beside the
predictions (online: virtual time + one-way delay; step by step: n x (2 x delay + mean statement
time)) and the thesis's figures. ``--json`` prints one document; ``--out DIR`` writes
``results.json`` and ``results.csv``. The exit status is 1 when a run failed.
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
from pathlib import Path

from server.cli import print_json

MAX_RUNS = 1000
MAX_DELAY_MS = 60_000.0


def _cmd_approach(args: argparse.Namespace) -> int:
    import logging

    from shared.cells.loader import DEFAULT_CELL
    from shared.errors import InputError

    if args.runs < 1 or args.runs > MAX_RUNS:
        raise InputError(f"--runs must be between 1 and {MAX_RUNS}; got {args.runs}")
    if not math.isfinite(args.delay_ms) or not 0.0 <= args.delay_ms <= MAX_DELAY_MS:
        raise InputError(f"--delay-ms must be between 0 and {MAX_DELAY_MS:g}; got {args.delay_ms:g}")
    if args.seed < 0:
        raise InputError(f"--seed must be 0 or more; got {args.seed}")
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a folder")
    cell = Path(args.cell) if args.cell else DEFAULT_CELL

    if not getattr(args, "verbose", False):
        logging.getLogger("httpx").setLevel(logging.WARNING)  # not a line per API call of the runs
    from tqdm import tqdm

    from server.trials.approach import run_batch
    from server.trials.report import table_lines, write_results
    from server.trials.script import approach_script

    script = approach_script(cell)  # a missing or unusable cell is one line here, before any session starts
    log_dir = Path(tempfile.mkdtemp(prefix="teleprog-trial-"))
    bar = tqdm(total=2 * args.runs, desc="approach trial", unit="mode", file=sys.stderr, disable=None, leave=False)
    done_runs = 0

    def after_run(run) -> None:
        nonlocal done_runs
        done_runs += 1
        bar.n = 2 * done_runs
        bar.set_postfix_str(f"run {done_runs}/{args.runs} {'ok' if run.success else 'FAILED'}")
        bar.refresh()

    try:
        report = run_batch(script, runs=args.runs, delay_ms=args.delay_ms, seed=args.seed, log_dir=log_dir,
                           on_mode=lambda mode: bar.update(1), on_run=after_run)
    finally:
        bar.close()
    summary = report.summary
    if out is not None:
        written = write_results(report, out)
    if args.json:
        print_json(report.model_dump(mode="json"))
    else:
        print("\n".join(table_lines(summary)))
        if out is not None:
            print("wrote " + ", ".join(str(p) for p in written))
    if summary.runs_succeeded < summary.runs_total:
        failed = [r for r in summary.runs if not r.success]
        print(f"teleprog: error: {len(failed)} of {summary.runs_total} run(s) failed; first: run {failed[0].index}: "
              f"{failed[0].failure} (session logs in {log_dir})", file=sys.stderr)
        return 1
    shutil.rmtree(log_dir, ignore_errors=True)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("trial", help="the thesis's trials (4.6) as repeatable experiments on real sessions: approach")
    kinds = p.add_subparsers(dest="trial_kind", required=True, parser_class=type(p))
    a = kinds.add_parser(
        "approach", help="online teleprogramming against step by step: 4 statements of about 1 s across the delay"
    )
    a.add_argument("--runs", type=int, default=1, metavar="N", help="how many runs, each a fresh session (default 1)")
    a.add_argument("--delay-ms", type=float, default=3000.0, metavar="D", help="link delay each way, ms (default 3000)")
    a.add_argument("--seed", type=int, default=0, metavar="S",
                   help="seed of the worlds: run i's telerobot world is seeded S*1000+i (default 0)")
    a.add_argument("--cell", default=None, metavar="CELL", help="cell file with a 'peg' (default assets/cells/peg_in_hole.toml)")
    a.add_argument("--json", action="store_true", help="print one JSON document: {\"summary\": ...}")
    a.add_argument("--out", metavar="DIR", default=None, help="write DIR/results.json and DIR/results.csv")
    a.set_defaults(handler=_cmd_approach)
