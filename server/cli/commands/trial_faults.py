"""``teleprog trial faults``: a surprise campaign, thousands of fault-injected runs in virtual time
judged from the physics (``server.trials.faults``).

``--json`` prints the summary (``runs``, ``faults``, ``caught``, ``missed``, ``false_stops``,
``stop_latency_ms``, ``misses`` with their seeds ...); ``--out DIR`` writes ``results.json`` (the
summary and every run) and ``outcomes.png``. ``--replay SEED`` runs one run again alone, with the
campaign's other flags, prints it whole (its fault, verdict, statuses and robot times) and records
it as an MCAP file (``server.trials.faults.recording``). The
exit is 1 when a run was missed (or hung), so a campaign can gate a change.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from server.cli import print_json

HELP = "a surprise campaign: fault-injected runs in virtual time, judged from the physics"


def _request(args: argparse.Namespace):
    from pydantic import ValidationError

    from server.trials.batch import TrialWorld
    from server.trials.faults.campaign import MAX_RUNS, CampaignRequest
    from server.cli.commands.trial import check_scheduler, flag_error, out_folder
    from server.trials.faults.catalogue import FAULT_KINDS, check_kinds
    from shared.errors import InputError

    if args.clock != "virtual":
        raise InputError("--clock: fault campaigns run in virtual time only (--clock virtual)")
    if not 1 <= args.runs <= MAX_RUNS:
        raise InputError(f"--runs must be between 1 and {MAX_RUNS}; got {args.runs}")
    for flag, value in (("--delay-ms", args.delay_ms), ("--jitter-ms", args.jitter_ms), ("--drop-probability", args.drop_probability)):
        if not math.isfinite(value) or value < 0:
            raise InputError(f"{flag} must be a finite number, 0 or more; got {value:g}")
    kinds = check_kinds(tuple(args.kind) if args.kind else FAULT_KINDS)
    if args.program is not None and not Path(args.program).is_file():
        raise InputError(f"--program {args.program}: no such file")
    check_scheduler(args.scheduler)
    out = out_folder(args.out)
    try:
        world = TrialWorld(object_offset_mm=args.object_offset_mm, force_noise_n=args.force_noise_n)
        request = CampaignRequest(runs=args.runs, seed=args.seed, delay_ms=args.delay_ms, jitter_ms=args.jitter_ms,
                                  drop_probability=args.drop_probability, program=args.program, mode=args.mode,
                                  kinds=kinds, world=world, workers=args.workers, scheduler=args.scheduler)
    except ValidationError as exc:
        raise flag_error(exc) from None
    return request, out


def _cmd_faults(args: argparse.Namespace) -> int:
    import logging

    from shared.cells.loader import DEFAULT_CELL

    request, out = _request(args)
    if not getattr(args, "verbose", False):  # a line per fault from the robot's log would drown the table
        for name in ("robot_sim", "distributed"):
            logging.getLogger(name).setLevel(logging.ERROR)
    cell = str(Path(args.cell) if args.cell else DEFAULT_CELL)
    from server.trials.faults.campaign import program_texts

    program_texts(cell, request.program)  # a bad cell or program is one line before anything runs
    if args.replay is not None:
        return _replay(request, cell, args)
    from tqdm import tqdm

    from server.trials.faults.campaign import run_campaign
    from server.trials.faults.plots import outcome_plot
    from server.trials.faults.results import FaultReport, summarize, table_lines

    bar = tqdm(total=request.runs, desc="fault campaign", unit="run", file=sys.stderr, disable=None, leave=False)
    missed = 0

    def done(runs) -> None:
        nonlocal missed
        missed += sum(r.outcome == "missed" for r in runs)
        bar.update(len(runs))
        bar.set_postfix_str(f"{missed} missed" if missed else "none missed")

    try:
        runs, wall = run_campaign(request, cell, on_done=done)
    finally:
        bar.close()
    summary = summarize(runs, seed=request.seed, delay_ms=request.delay_ms, jitter_ms=request.jitter_ms,
                        drop_probability=request.drop_probability, program=request.program or "peg transfer",
                        mode=request.mode, world=request.world.described(cell), wall_s=wall)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "results.json").write_text(FaultReport(summary=summary, runs=runs).model_dump_json(indent=1))
        outcome_plot(summary, out / "outcomes.png")
    if args.json:
        print_json(summary.model_dump(mode="json"))
    else:
        print("\n".join(table_lines(summary)))
        if out is not None:
            print(f"wrote {out / 'results.json'}, {out / 'outcomes.png'}")
    bad = [r for r in runs if r.outcome in ("missed", "hung")]
    if bad:
        first = bad[0]
        print(f"teleprog: error: {len(bad)} of {len(runs)} run(s) {first.outcome}; first: seed {first.seed}: "
              f"{first.fault.describe()}: {first.why} (replay with --replay {first.seed})", file=sys.stderr)
        return 1
    return 0


def _replay(request, cell: str, args: argparse.Namespace) -> int:
    from server.trials.faults.campaign import replay

    out = Path(args.out) if args.out else Path.cwd()
    out.mkdir(parents=True, exist_ok=True)
    mcap = out / f"teleprog-fault-{args.replay}.mcap"
    run = replay(request, cell, args.replay, record=mcap)
    print(f"recorded the run in {mcap}", file=sys.stderr)
    if args.json:
        print_json(run.model_dump(mode="json"))
    else:
        print(f"run {run.seed} (world {run.world_seed}): {run.fault.describe()} -> {run.outcome}"
              + (f": {run.why}" if run.why else ""))
        if run.note:
            print(f"  fault: {run.note}")
        if run.robot_reason:
            print(f"  the robot: {run.robot_reason}")
        if run.latency_ms is not None:
            print(f"  stop {run.stop_s:.2f} s ({run.stop_state}), {run.latency_ms:g} ms after the onset "
                  f"({run.onset_how}); stopped within {run.stop_distance_mm:g} mm")
        for s in run.statements:
            robot = "" if s.robot_run_s is None else f" ({s.robot_run_s:.3f} s on the robot)"
            print(f"  {s.status:8s} {s.text}{robot}" + (f": {s.reason}" if s.reason else ""))
        for h in run.halts:
            print(f"  halted: {h}")
    return 1 if run.outcome in ("missed", "hung") else 0


def register(kinds: argparse._SubParsersAction) -> None:
    a = kinds.add_parser("faults", help=HELP, description=HELP)
    a.add_argument("--runs", type=int, default=200, metavar="N", help="runs, one in ten without a fault (default 200)")
    a.add_argument("--seed", type=int, default=0, metavar="S", help="the campaign's seed: run i's seed is S*1000000+i (default 0)")
    a.add_argument("--clock", choices=("virtual",), default="virtual", help="virtual time (the only clock a campaign runs on)")
    a.add_argument("--delay-ms", type=float, default=3000.0, metavar="D", help="link delay each way, ms (default 3000)")
    a.add_argument("--jitter-ms", type=float, default=0.0, metavar="J", help="extra delay drawn up to J ms per message (default 0)")
    a.add_argument("--drop-probability", type=float, default=0.0, metavar="P",
                   help="chance a message is lost, cutting the connection (default 0; at most 0.01)")
    a.add_argument("--program", default=None, metavar="FILE", help="a program file to run (default: the peg transfer for the cell)")
    a.add_argument("--cell", default=None, metavar="CELL", help="cell file (default assets/cells/peg_in_hole.toml)")
    a.add_argument("--mode", choices=("composite", "step"), default="composite",
                   help="composite control (each statement as its zone's regime says) or step by step (default composite)")
    a.add_argument("--kind", action="append", default=None, metavar="KIND", help="draw only these fault kinds (repeatable; default all)")
    a.add_argument("--object-offset-mm", type=float, default=1.0, metavar="MM",
                   help="the real plate and objects up to MM off the model (default 1)")
    a.add_argument("--force-noise-n", type=float, default=0.05, metavar="N", help="force sensor noise, std in N (default 0.05)")
    a.add_argument("--workers", type=int, default=1, metavar="K", help="run K groups of runs at once in local processes (default 1)")
    a.add_argument("--scheduler", default=None, metavar="URL", help="run on the Dask cluster at URL (tcp://HOST:PORT)")
    a.add_argument("--replay", type=int, default=None, metavar="SEED",
                   help="run the run with this seed again, alone, print it whole and record it (DIR/teleprog-fault-SEED.mcap with --out, else here)")
    a.add_argument("--json", action="store_true", help="print the summary (or the replayed run) as one JSON document")
    a.add_argument("--out", metavar="DIR", default=None, help="write DIR/results.json (every run) and DIR/outcomes.png")
    a.set_defaults(handler=_cmd_faults)
