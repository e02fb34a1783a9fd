"""One batch of a trial, from a typed request to its report: what ``teleprog trial KIND`` and
``POST /api/trials`` both run.

``prepare`` turns a request into run specs (the approach script or the transfer program for the
cell, the composite mode's regimes), ``execute_batch`` runs them on the executor asked for, and
``report_of`` summarises them into the kind's report, its terminal table, and the writers of its
files (JSON, CSV, plots).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from server.trials.batch import RunSpec, TrialWorld, open_executor, run_all, world_seed
from shared.errors import InputError

TrialKind = Literal["approach", "grasp", "extract", "insert", "transfer"]
MAX_RUNS = 10_000
MAX_DELAY_MS = 60_000.0
MAX_WORKERS = 64


class TrialRequest(BaseModel):
    """A batch: ``runs`` runs of each mode of ``kind`` (all its modes unless ``modes`` names some)."""

    model_config = ConfigDict(frozen=True, allow_inf_nan=False, extra="forbid")

    kind: TrialKind
    runs: int = Field(1, ge=1, le=MAX_RUNS)
    delay_ms: float = Field(3000.0, ge=0.0, le=MAX_DELAY_MS, description="link delay each way, ms")
    seed: int = Field(0, ge=0, le=10**9, description="run i's world is seeded seed*1000+i")
    clock: Literal["real", "virtual"] = "real"
    modes: tuple[str, ...] | None = Field(None, max_length=8, description="the transfer trial's modes; default all")
    world: TrialWorld = Field(default_factory=TrialWorld)
    workers: int = Field(1, ge=1, le=MAX_WORKERS, description="local processes running runs at once")
    scheduler: str | None = Field(None, max_length=200, description="a Dask scheduler's address, tcp://HOST:PORT")


@dataclass(frozen=True)
class Prepared:
    request: TrialRequest
    cell: str
    modes: tuple[str, ...]
    specs: list[RunSpec]
    statements: int  # the approach's statement count (0 for the other kinds)


def prepare(request: TrialRequest, cell: str | Path, log_dir: Path) -> Prepared:
    """The batch's specs; a cell without what the kind needs is an ``InputError`` here, before
    any run starts."""
    cell = str(cell)
    common = dict(delay_ms=request.delay_ms, clock=request.clock, log_dir=str(log_dir))
    seeds = [request.world.settings(world_seed(request.seed, i)) for i in range(request.runs)]
    if request.kind == "approach":
        from server.trials.script import approach_script

        script = approach_script(cell)
        modes: tuple[str, ...] = ("online+step_by_step",)
        specs = [RunSpec("approach", modes[0], i, w, script=script, **common) for i, w in enumerate(seeds)]
        return Prepared(request, cell, modes, specs, len(script.statements))
    from server.trials.kinds import KIND_MODES, regime_schedule
    from server.trials.programs import transfer_program

    program = transfer_program(cell)
    modes = tuple(request.modes) if request.modes else KIND_MODES[request.kind]
    bad = [m for m in modes if m not in KIND_MODES[request.kind]]
    if bad:
        raise InputError(f"--mode {bad[0]}: the {request.kind} trial's modes are {', '.join(KIND_MODES[request.kind])}")
    schedule = tuple(regime_schedule(cell, program.texts())) if "composite" in modes else None
    specs = [RunSpec(request.kind, m, i, w, program=program, schedule=schedule, **common)
             for m in modes for i, w in enumerate(seeds)]
    return Prepared(request, cell, modes, specs, 0)


def execute_batch(prepared: Prepared, on_done: Callable[[object], None] = lambda result: None, *,
                  isolated: bool = False) -> list:
    """Every run's result in spec order (virtual runs: the cell's models built here first, so
    forked workers start with them; ``isolated``: in a spawned process, nothing run here)."""
    request = prepared.request
    if request.clock == "virtual" and request.scheduler is None and not isolated:
        from server.trials.virtual_clock import warm

        warm(prepared.cell)
    with open_executor(request.workers, request.scheduler, isolated=isolated) as executor:
        return run_all(prepared.specs, executor, on_done=on_done)


@dataclass(frozen=True)
class BatchReport:
    report: BaseModel  # ApproachReport or KindReport: ``{"summary": ...}``
    lines: list[str]  # the terminal (Markdown) table
    write: Callable[[Path], list[Path]]  # results.json, results.csv and the plots into a folder


def report_of(prepared: Prepared, results: list) -> BatchReport:
    request = prepared.request
    world = request.world.described(prepared.cell)
    if request.kind == "approach":
        from server.trials.plots import approach_plots
        from server.trials.report import table_lines, write_results
        from server.trials.results import ApproachReport, summarize

        summary = summarize(results, delay_ms=request.delay_ms, seed=request.seed, cell=prepared.cell,
                            statements=prepared.statements, clock=request.clock, world=world)
        report = ApproachReport(summary=summary)
        return BatchReport(report, table_lines(summary), lambda out: write_results(report, out) + approach_plots(summary, out))
    from server.trials.kind_results import KindReport, summarize_kind
    from server.trials.plots import kind_plots
    from server.trials.report import kind_table_lines, write_kind_results

    summary = summarize_kind(request.kind, prepared.modes, results, clock=request.clock, delay_ms=request.delay_ms,
                             seed=request.seed, cell=prepared.cell, world=world)
    report = KindReport(summary=summary)
    return BatchReport(report, kind_table_lines(summary), lambda out: write_kind_results(report, out) + kind_plots(summary, out))


def broken_runs(kind: str, results: list) -> list:
    """Runs that failed for a reason other than the trial's own outcome: every failed approach
    run; for the other kinds, runs that could not reach their step for a reason other than the
    setup's own failure (a session that did not start, a wait that ran out)."""
    if kind == "approach":
        return [r for r in results if not r.success]
    return [r for r in results if not r.reached and not (r.failure or "").startswith("setup: ")]
