"""A fault campaign: many runs of a program in virtual time, each with one seeded fault, judged
from the physics (``teleprog trial faults``).

Runs come in groups of ``GROUP`` on one seeded world: the group's first run is fault-free (the
campaign's false-stop runs, and the twin its other runs are compared with tick for tick), the
others each get one fault drawn from the catalogue. A group is one task for the executor (this
process, local processes, or a Dask cluster), so a worker builds the cell's models and the
compiled physics model once (``cell_parts``, ``_compiled``: per process) and its fault-free twin
once per group.

A run's seed (``run_seed``) names it alone: ``S * 1_000_000 + i`` for run ``i`` of the campaign
seeded ``S``. Its world is the group's (``S * 1000 + i // GROUP``), its fault is drawn from a
generator seeded by the run's seed; ``--replay SEED`` runs the group's twin and then that run, and
gets the same statuses and the same robot times.
"""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from server.trials.batch import TrialWorld, open_executor
from server.trials.faults.catalogue import FAULT_KINDS, CleanTrace, Fault, check_kinds, draw_fault
from server.trials.faults.inject import Injector
from server.trials.faults.judge import SETTLE_S, Judge, RunOver
from server.trials.faults.results import FaultRun, FaultStatement
from server.trials.session import TrialError
from shared.errors import InputError

log = logging.getLogger(__name__)

GROUP = 10
"""Runs per world: the first fault-free, the other nine with a fault each (10 % fault-free runs)."""
RUN_SEED_BASE = 1_000_000
MAX_RUNS = 10_000  # groups stay under 1000 a campaign: world seeds S*1000+group never collide
Mode = Literal["composite", "step"]


class CampaignRequest(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    runs: int = Field(200, ge=1, le=MAX_RUNS)
    seed: int = Field(0, ge=0, le=10**6)
    delay_ms: float = Field(3000.0, ge=0.0, le=60_000.0)
    jitter_ms: float = Field(0.0, ge=0.0, le=60_000.0)
    drop_probability: float = Field(0.0, ge=0.0, le=0.01, description="chance a message is lost (cuts the connection)")
    program: str | None = Field(None, description="a program file; default: the peg transfer for the cell")
    mode: Mode = "composite"
    kinds: tuple[str, ...] = FAULT_KINDS
    world: TrialWorld = Field(default_factory=lambda: TrialWorld(object_offset_mm=1.0))
    workers: int = Field(1, ge=1, le=64)
    scheduler: str | None = None


def run_seed(seed: int, index: int) -> int:
    return seed * RUN_SEED_BASE + index


def split_seed(seed: int) -> tuple[int, int]:
    """A run's seed -> (the campaign's seed, the run's index)."""
    if seed < 0:
        raise InputError(f"--replay must be a run's seed (0 or more); got {seed}")
    return divmod(seed, RUN_SEED_BASE)


@dataclass(frozen=True)
class GroupSpec:
    """One world's runs (picklable: it travels to a worker)."""

    cell: str
    texts: tuple[str, ...]
    mode: Mode
    delay_ms: float
    jitter_ms: float
    drop_probability: float
    world: TrialWorld
    kinds: tuple[str, ...]
    seed: int
    group: int
    indices: tuple[int, ...]  # the runs of this group to report (the twin always runs)


def program_texts(cell: str, program: str | None) -> tuple[str, ...]:
    """The statements a run sends: the program file's, or the peg transfer for the cell."""
    if program is None:
        from server.trials.programs import transfer_program

        return tuple(transfer_program(cell).texts())
    from shared.language.formatter import format_statement
    from shared.language.parser import parse_program, read_program_file

    parsed = parse_program(read_program_file(program), path=program)
    if not parsed.ok:
        first = parsed.errors[0]
        raise InputError(f"--program {program}:{first.line}:{first.col}: {first.message}")
    if not parsed.statements:
        raise InputError(f"--program {program}: no statements")
    return tuple(format_statement(s) for s in parsed.statements)


@functools.lru_cache(maxsize=16)
def _schedule(cell: str, texts: tuple[str, ...]) -> tuple[str, ...]:
    from server.trials.kinds import regime_schedule

    return tuple(regime_schedule(cell, list(texts)))


def _pieces(spec: GroupSpec):
    from server.trials.kinds import Piece, composite_pieces

    if spec.mode == "step":
        return [Piece((t,), "step") for t in spec.texts]
    return composite_pieces(spec.texts, _schedule(spec.cell, spec.texts))


def _session(spec: GroupSpec, fault: Fault):
    from server.trials.virtual_clock import VirtualDriver, cell_parts
    from shared.link.core import LinkParams

    world = spec.world.settings(spec.seed * 1000 + spec.group)
    if fault.kind == "heavier":  # the world is so from the start
        world = world.model_copy(update={"object_mass_factor": fault.magnitude})
    elif fault.kind == "friction":
        base = world.friction if world.friction is not None else cell_parts(spec.cell).cell.physics.friction
        world = world.model_copy(update={"friction": min(10.0, base * fault.magnitude)})
    link = LinkParams(delay_s=spec.delay_ms / 1e3, jitter_s=spec.jitter_ms / 1e3, drop_probability=spec.drop_probability,
                      seed=spec.seed * 1000 + spec.group)
    driver = VirtualDriver(spec.cell, world, spec.delay_ms / 1e3, link=link)
    driver.wait_welcome()
    return driver


def _run(spec: GroupSpec, fault: Fault, twin: CleanTrace | None, index: int,
         record: Path | None = None) -> tuple[FaultRun, CleanTrace | None]:
    from server.trials.kinds import execute

    driver = _session(spec, fault)
    t0 = driver.t
    trace = CleanTrace(dt=driver.dt, start=t0, end=t0, last_task_start=t0) if twin is None else None
    injector = None
    if fault.kind != "none":
        injector = Injector(fault, twin, t0)
        injector.attach(driver)
    judge = Judge(driver, fault, injector, twin, t0, record=trace)
    driver.observers.append(judge)
    recorder = None
    if record is not None:
        from server.trials.faults.recording import RunRecorder

        recorder = RunRecorder(record, fault)
        driver.observers.append(recorder)
    pieces = _pieces(spec)
    finished, error = False, ""
    try:
        execute(driver, pieces, spec.delay_ms / 1e3)
        finished = True
        if judge.stop_at is not None:  # a stop the console heard of before the judge's settling ended
            driver.wait_until(judge.stop_at + SETTLE_S + 2 * driver.dt)
    except RunOver:
        pass
    except TrialError as exc:
        error = str(exc)
    sent = driver.sent
    done = finished and len(sent) == len(spec.texts) and all(r.status == "done" for r in sent)
    if finished and not done and judge.stop_at is None and not error:
        bad = next((r for r in sent if r.status != "done"), None)
        error = ("the program ended without a stop and without every statement done: "
                 + (f"{bad.text}: {bad.status}: {bad.reason}" if bad else f"{len(sent)} of {len(spec.texts)} sent"))
    verdict = judge.verdict(driver, finished=done, error=error)
    ends = [r.finished_at for r in sent if r.finished_at is not None]
    run = verdict.model_copy(update={
        "seed": run_seed(spec.seed, index), "world_seed": spec.seed * 1000 + spec.group,
        "program_s": round((max(ends) if ends else driver.t) - t0, 4),
        "statements": [FaultStatement(text=r.text, status=r.status, reason=r.reason,
                                      robot_run_s=None if r.robot_run_s is None else round(r.robot_run_s, 6)) for r in sent],
        "halts": list(driver.halts),
        "robot_reason": next((why for t, why in driver.robot_said if judge.stop_at is not None and t >= judge.stop_at - 1e-9),
                             judge.halted),
    })
    if trace is not None:
        trace.end = judge.last_busy
        trace.last_task_start = judge.last_task_start
        trace.end_holes = {name: peg.in_hole for name, peg in driver.world.pegs.items()}
    if recorder is not None:
        recorder.close(run, driver.t)
    return run, trace


def fault_of(spec: GroupSpec, index: int, twin: CleanTrace) -> Fault:
    """Run ``index``'s fault: none for a group's first run, else drawn from its own seed."""
    if index % GROUP == 0:
        return Fault(kind="none")
    from server.trials.virtual_clock import cell_parts

    cell = cell_parts(spec.cell).cell
    rng = np.random.default_rng(run_seed(spec.seed, index))
    objects = [o.name for o in cell.objects if o.movable]
    return draw_fault(rng, spec.kinds, twin, cell.robot.dof, objects)


def run_group(spec: GroupSpec) -> list[FaultRun]:
    """The group's fault-free twin, then each of its faulted runs asked for (a top-level function,
    so executors can ship it)."""
    first = spec.group * GROUP
    try:
        clean, twin = _run(spec, Fault(kind="none"), None, first)
    except Exception as exc:  # noqa: BLE001 - a run that raises is a result (hung), not the campaign's end
        log.exception("group %d's fault-free run raised", spec.group)
        return [_raised(spec, i, Fault(kind="none"), exc) for i in spec.indices]
    out = [clean] if first in spec.indices else []
    for index in spec.indices:
        if index == first:
            continue
        fault = fault_of(spec, index, twin)
        try:
            run, _ = _run(spec, fault, twin, index)
        except Exception as exc:  # noqa: BLE001
            log.exception("run %d raised", run_seed(spec.seed, index))
            run = _raised(spec, index, fault, exc)
        out.append(run)
    return out


def _raised(spec: GroupSpec, index: int, fault: Fault, exc: Exception) -> FaultRun:
    return FaultRun(seed=run_seed(spec.seed, index), world_seed=spec.seed * 1000 + spec.group, fault=fault,
                    outcome="hung", why=f"the run raised {type(exc).__name__}: {str(exc)[:300]}")


def group_specs(request: CampaignRequest, cell: str, indices: Sequence[int]) -> list[GroupSpec]:
    texts = program_texts(cell, request.program)
    check_kinds(request.kinds)
    groups: dict[int, list[int]] = {}
    for i in indices:
        groups.setdefault(i // GROUP, []).append(i)
    return [GroupSpec(cell=cell, texts=texts, mode=request.mode, delay_ms=request.delay_ms, jitter_ms=request.jitter_ms,
                      drop_probability=request.drop_probability, world=request.world, kinds=tuple(request.kinds),
                      seed=request.seed, group=g, indices=tuple(ix)) for g, ix in sorted(groups.items())]


def run_campaign(request: CampaignRequest, cell: str | Path,
                 on_done: Callable[[list[FaultRun]], None] = lambda runs: None) -> tuple[list[FaultRun], float]:
    """Every run of the campaign, in run order, and the wall time it took."""
    specs = group_specs(request, str(cell), range(request.runs))
    started = time.perf_counter()
    from concurrent.futures import as_completed

    if request.scheduler is None:
        from server.trials.virtual_clock import warm

        warm(str(cell))  # the models built before workers fork
        _schedule(str(cell), specs[0].texts) if request.mode == "composite" else None
    results: list[FaultRun] = []
    with open_executor(request.workers, request.scheduler) as executor:
        futures = [executor.submit(run_group, s) for s in specs]
        for future in as_completed(futures):
            runs = future.result()
            results += runs
            on_done(runs)
    results.sort(key=lambda r: r.seed)
    return results, time.perf_counter() - started


def replay(request: CampaignRequest, cell: str | Path, seed: int, record: Path | None = None) -> FaultRun:
    """Run ``seed`` again alone (after its group's twin), on the campaign's settings; ``record``:
    write the run as an MCAP file there (``server.trials.faults.recording``)."""
    campaign_seed, index = split_seed(seed)
    request = request.model_copy(update={"seed": campaign_seed})
    (spec,) = group_specs(request, str(cell), [index])
    first = spec.group * GROUP
    clean, twin = _run(spec, Fault(kind="none"), None, first, record=record if index == first else None)
    if index == first:
        return clean
    return _run(spec, fault_of(spec, index, twin), twin, index, record=record)[0]
