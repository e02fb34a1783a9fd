"""``teleprog trial KIND``: the thesis's trials (§4.6) as headless, repeatable experiments.

Kinds: ``approach`` (online teleprogramming against step by step), ``grasp`` (offline programming
with preview), ``extract`` and ``insert`` (the robot's sub-tasks under supervision), ``transfer``
(the whole peg transfer under segmented composite control, and under each single regime). Each run
is a fresh session: with ``--clock real`` (default) a whole ``teleprog up`` (telerobot, delayed link,
console) driven through the console's HTTP API; with ``--clock virtual`` the console's sender and
planner, the link and the telerobot in one process on a virtual clock (``server.trials``).

Run ``i``'s world is seeded ``S*1000+i`` with the offsets, noise, tilt, friction and clearance given, so a run is
repeatable alone. Runs go to ``--workers K`` local processes or a Dask cluster (``--scheduler``).
``--json`` prints one document (``{"summary": ...}``); ``--out DIR`` writes ``results.json``,
``results.csv`` and the plots. The approach trial exits 1 when a run failed; for the other kinds a
failed run is a result (the success rate), and the exit is 1 only when nothing could run.
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
from pathlib import Path

from server.cli import print_json

KINDS = {
    "approach": "online teleprogramming against step by step: 4 statements of about 1 s across the delay",
    "grasp": "alignment and grasp by offline programming with preview (thesis: 100 %)",
    "extract": "the robot's extraction sub-task under supervision (thesis: 95 %)",
    "insert": "the robot's insertion sub-task under supervision (thesis: 90 %)",
    "transfer": "the whole peg transfer: segmented composite control, and each single regime",
}


def check_scheduler(value: str | None) -> None:
    """``--scheduler``: a Dask scheduler's address, or nothing."""
    from shared.errors import InputError

    if value is not None and not value.startswith(("tcp://", "tls://", "inproc://", "ws://", "wss://")):
        raise InputError(f"--scheduler must be a Dask scheduler address such as tcp://127.0.0.1:8786; got {value!r}")


def out_folder(value: str | None) -> Path | None:
    """``--out``: a folder to write into (made when missing), not a file."""
    from shared.errors import InputError

    out = Path(value) if value else None
    if out is not None and out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a folder")
    return out


def flag_error(exc) -> Exception:
    """A request model's ``ValidationError`` as one line naming the flag of its first field."""
    from shared.errors import InputError

    first = exc.errors()[0]
    flag = "--" + str(first["loc"][0]).replace("_", "-")
    return InputError(f"{flag}: {first['msg']}")


def _request(args: argparse.Namespace):
    """The batch the flags ask for; a bad value is one line naming its flag."""
    from pydantic import ValidationError

    from server.trials.batch import TrialWorld
    from server.trials.runner import MAX_DELAY_MS, MAX_RUNS, MAX_WORKERS, TrialRequest
    from shared.errors import InputError

    if args.runs < 1 or args.runs > MAX_RUNS:
        raise InputError(f"--runs must be between 1 and {MAX_RUNS}; got {args.runs}")
    if not math.isfinite(args.delay_ms) or not 0.0 <= args.delay_ms <= MAX_DELAY_MS:
        raise InputError(f"--delay-ms must be between 0 and {MAX_DELAY_MS:g}; got {args.delay_ms:g}")
    if args.seed < 0:
        raise InputError(f"--seed must be 0 or more; got {args.seed}")
    if not 1 <= args.workers <= MAX_WORKERS:
        raise InputError(f"--workers must be between 1 and {MAX_WORKERS}; got {args.workers}")
    check_scheduler(args.scheduler)
    out = out_folder(args.out)
    try:
        world = TrialWorld(engine=args.world, object_offset_mm=args.object_offset_mm, force_noise_n=args.force_noise_n,
                           grasp_tilt_deg=args.grasp_tilt_deg, friction=args.friction, clearance_mm=args.clearance_mm)
        request = TrialRequest(kind=args.trial_kind, runs=args.runs, delay_ms=args.delay_ms, seed=args.seed,
                               clock=args.clock, modes=tuple(args.mode) if args.mode else None, world=world,
                               workers=args.workers, scheduler=args.scheduler)
    except ValidationError as exc:
        raise flag_error(exc) from None
    return request, out


def _cmd_trial(args: argparse.Namespace) -> int:
    import logging

    from shared.cells.loader import DEFAULT_CELL

    request, out = _request(args)
    if not getattr(args, "verbose", False):
        logging.getLogger("httpx").setLevel(logging.WARNING)  # not a line per API call of the runs
        logging.getLogger("distributed").setLevel(logging.WARNING)
    from tqdm import tqdm

    from server.trials.runner import broken_runs, execute_batch, prepare, report_of

    cell = str(Path(args.cell) if args.cell else DEFAULT_CELL)
    log_dir = Path(tempfile.mkdtemp(prefix="teleprog-trial-"))
    prepared = prepare(request, cell, log_dir)  # a missing or unusable cell is one line here
    bar = tqdm(total=len(prepared.specs), desc=f"{request.kind} trial", unit="run", file=sys.stderr, disable=None, leave=False)
    failed = 0

    def done(result) -> None:
        nonlocal failed
        failed += not result.success
        bar.update(1)
        bar.set_postfix_str(f"{failed} failed" if failed else "all ok")

    try:
        results = execute_batch(prepared, on_done=done)
    finally:
        bar.close()
    batch = report_of(prepared, results)
    written = batch.write(out) if out is not None else []
    if args.json:
        print_json(batch.report.model_dump(mode="json"))
    else:
        print("\n".join(batch.lines))
        if written:
            print("wrote " + ", ".join(str(p) for p in written))
    broken = broken_runs(request.kind, results)
    if broken:
        first = broken[0]
        print(f"teleprog: error: {len(broken)} of {len(results)} run(s) failed; first: run {first.index}: {first.failure}"
              + (f" (session logs in {log_dir})" if args.clock == "real" else ""), file=sys.stderr)
        return 1
    shutil.rmtree(log_dir, ignore_errors=True)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("trial", help="the thesis's trials (4.6) as repeatable experiments: " + ", ".join(KINDS))
    kinds = p.add_subparsers(dest="trial_kind", required=True, parser_class=type(p))
    for kind, help_text in KINDS.items():
        a = kinds.add_parser(kind, help=help_text.replace("%", "%%"), description=help_text)  # help strings are %-formatted
        a.add_argument("--runs", type=int, default=1, metavar="N", help="how many runs (of each mode), each a fresh session (default 1)")
        a.add_argument("--delay-ms", type=float, default=3000.0, metavar="D", help="link delay each way, ms (default 3000)")
        a.add_argument("--seed", type=int, default=0, metavar="S",
                       help="seed of the worlds: run i's telerobot world is seeded S*1000+i (default 0)")
        a.add_argument("--cell", default=None, metavar="CELL",
                       help="cell file with a movable peg in a hole (default assets/cells/peg_in_hole.toml)")
        a.add_argument("--clock", choices=("real", "virtual"), default="real",
                       help="real: whole teleprog up sessions; virtual: console, link and robot in one process on a virtual clock")
        a.add_argument("--workers", type=int, default=1, metavar="K", help="run K runs at once in local processes (default 1)")
        a.add_argument("--scheduler", default=None, metavar="URL", help="run on the Dask cluster at URL (tcp://HOST:PORT)")
        a.add_argument("--object-offset-mm", type=float, default=2.0, metavar="MM",
                       help="the real peg and holes lie up to MM off the model in x and y (default 2)")
        a.add_argument("--force-noise-n", type=float, default=0.05, metavar="N", help="force sensor noise, std in N (default 0.05)")
        a.add_argument("--grasp-tilt-deg", type=float, default=0.0, metavar="DEG",
                       help="the peg settles this much tilted in the fingers once out of its hole (default 0)")
        a.add_argument("--friction", type=float, default=None, metavar="MU",
                       help="sliding friction of the cell's contacts (default: the cell's [physics] value, 0.3)")
        a.add_argument("--clearance-mm", type=float, default=None, metavar="MM",
                       help="fit of the peg in its holes (default: the cell's geometry, 0.03 mm)")
        a.add_argument("--world", choices=("physics", "kinematic"), default="physics",
                       help="the telerobot's world: MuJoCo contact physics (default) or the kinematic stand-in")
        if kind == "transfer":
            a.add_argument("--mode", action="append", default=None, metavar="MODE",
                           help="composite, free, quasi or operation (repeatable; default all four)")
        a.add_argument("--json", action="store_true", help="print one JSON document: {\"summary\": ...}")
        a.add_argument("--out", metavar="DIR", default=None, help="write DIR/results.json, DIR/results.csv and the plots (PNG)")
        a.set_defaults(handler=_cmd_trial)
        if kind != "transfer":
            a.set_defaults(mode=None)
    from server.cli.commands import trial_faults

    trial_faults.register(kinds)
