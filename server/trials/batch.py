"""A batch of trial runs: the seeded worlds, one spec per run, and the executor that runs them.

Runs are independent (each its own session and world), so the batch hands them to a
``concurrent.futures`` executor and merges the results in spec order, whichever executor ran
them: in this process (``--workers 1``), local processes (``--workers K``), or a Dask distributed
cluster (``--scheduler tcp://HOST:PORT``; ``Client.get_executor()`` is a ``concurrent.futures``
executor). A run's world is seeded from the batch's seed and the run's index only, so a run is
repeatable alone and the same batch gives the same table on any executor.
"""

from __future__ import annotations

import logging
import math
import multiprocessing
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from robot_sim.settings import WorldSettings
from server.trials.drivers import Clock
from server.trials.kind_results import KindRun
from server.trials.programs import TransferProgram
from server.trials.results import RunResult
from server.trials.script import ApproachScript

log = logging.getLogger(__name__)


class TrialWorld(BaseModel):
    """How the trials' real world departs from the model (``robot_sim.settings.WorldSettings``),
    in the units people type. Each run gets these with its own seed."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    engine: Literal["physics", "kinematic"] = Field("physics", description="the telerobot's world: MuJoCo contact physics or the kinematic stand-in")
    object_offset_mm: float = Field(2.0, ge=0.0, le=20.0, description="max xy offset of the plate (with its holes and what stands in them), mm")
    force_noise_n: float = Field(0.05, ge=0.0, le=10.0, description="std of the force sensor's noise, N")
    grasp_tilt_deg: float = Field(0.0, ge=-20.0, le=20.0, description="tilt the peg settles at in the fingers once out of its hole, deg")
    friction: float | None = Field(None, ge=0.0, le=10.0, description="sliding friction of the cell's contacts (default: the cell's)")
    clearance_mm: float | None = Field(None, ge=0.0, le=5.0, description="fit of the peg in its holes, mm (default: the cell's geometry)")

    def settings(self, seed: int) -> WorldSettings:
        return WorldSettings(engine=self.engine, seed=seed, object_offset=self.object_offset_mm / 1e3,
                             force_noise=self.force_noise_n, grasp_tilt=math.radians(self.grasp_tilt_deg),
                             friction=self.friction,
                             clearance=None if self.clearance_mm is None else self.clearance_mm / 1e3)

    def described(self, cell: str | Path) -> dict[str, object]:
        """These settings with the engine's name and every physics parameter the runs use (the
        cell's ``[physics]`` table with the overrides), for a summary."""
        out: dict[str, object] = self.model_dump()
        if self.engine == "kinematic":
            return {**out, "engine": "kinematic"}
        import mujoco

        from shared.cells.loader import load_cell

        params = load_cell(cell).physics.with_overrides(
            friction=self.friction, clearance=None if self.clearance_mm is None else self.clearance_mm / 1e3)
        return {**out, "engine": "mujoco", "mujoco_version": mujoco.__version__, "physics": params.as_dict()}


def world_seed(seed: int, index: int) -> int:
    """The seed of run ``index``'s world: repeatable alone, different for every run of a batch."""
    return seed * 1000 + index


@dataclass(frozen=True)
class RunSpec:
    """Everything one run needs, picklable (it travels to a worker process or a Dask worker)."""

    kind: str
    mode: str
    index: int
    world: WorldSettings
    delay_ms: float
    clock: Clock
    log_dir: str
    script: ApproachScript | None = None  # the approach trial
    program: TransferProgram | None = None  # the other kinds
    schedule: tuple[str, ...] | None = None  # the composite mode's regimes


def run_spec(spec: RunSpec) -> RunResult | KindRun:
    """Run one spec (a top-level function, so executors can ship it)."""
    if spec.kind == "approach":
        from server.trials.approach import run_one

        return run_one(spec.script, index=spec.index, world=spec.world, delay_ms=spec.delay_ms,
                       log_dir=Path(spec.log_dir), clock=spec.clock)
    from server.trials.kinds import run_one

    return run_one(spec.kind, spec.mode, spec.program, index=spec.index, world=spec.world, delay_ms=spec.delay_ms,
                   clock=spec.clock, log_dir=Path(spec.log_dir), schedule=spec.schedule)


class _Inline(Executor):
    """Runs each submission at once in this process (``--workers 1``)."""

    def submit(self, fn, /, *args, **kwargs):
        from concurrent.futures import Future

        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller through the future
            future.set_exception(exc)
        return future


@contextmanager
def open_executor(workers: int = 1, scheduler: str | None = None, *, isolated: bool = False) -> Iterator[Executor]:
    """The executor for a batch: Dask at ``scheduler``, else ``workers`` local processes (forked,
    so the parent's imports and cell models come along), else this process. ``isolated``: never
    this process nor a fork of it (a fresh spawned process: for a console, whose threads a fork
    would copy mid-work and whose event loop the runs would slow)."""
    if isolated and not scheduler:
        with ProcessPoolExecutor(max_workers=max(1, workers), mp_context=multiprocessing.get_context("spawn")) as pool:
            yield pool
        return
    if scheduler:
        from distributed import Client

        with Client(scheduler, timeout="30s") as client:
            yield client.get_executor(pure=False)
        return
    if workers <= 1:
        yield _Inline()
        return
    methods = multiprocessing.get_all_start_methods()
    context = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        yield pool


def run_all(specs: Sequence[RunSpec], executor: Executor,
            on_done: Callable[[RunResult | KindRun], None] = lambda result: None) -> list[RunResult | KindRun]:
    """Every spec's result, in spec order; ``on_done`` after each as it completes (a progress bar)."""
    futures = {executor.submit(run_spec, spec): i for i, spec in enumerate(specs)}
    results: list[RunResult | KindRun | None] = [None] * len(specs)
    for future in as_completed(futures):
        result = future.result()
        results[futures[future]] = result
        on_done(result)
    return [r for r in results if r is not None]
