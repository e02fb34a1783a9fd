"""Results of the grasp, extract, insert and transfer trials: per run, and per kind and mode
with success rates (Wilson 95 % intervals), median times and the thesis's figure beside ours.

A run whose untimed setup failed (the peg stuck while an insertion trial took it out, say) did
not reach the trial's own step: it is counted and listed, but left out of the success rate,
which is the rate of the step itself, as the thesis reports it.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from server.trials.results import StatementTiming, _Model
from server.trials.stats import iqr, med, wilson_interval

# §4.6's results: alignment and grasp 100 %, extraction 95 %, insertion 90 %; the combined trial
# "completed the task" (no rate given: shown as 1.0 for the composite mode only)
THESIS_SUCCESS: dict[tuple[str, str], float] = {
    ("grasp", "offline"): 1.00,
    ("extract", "supervised"): 0.95,
    ("insert", "supervised"): 0.90,
    ("transfer", "composite"): 1.00,
}


class KindRun(_Model):
    kind: str
    mode: str
    index: int
    world_seed: int
    delay_ms: float
    clock: Literal["real", "virtual"]
    reached: bool = Field(description="the untimed setup succeeded, so the trial's own step ran")
    success: bool
    failure: str | None = None
    statements: list[StatementTiming] = Field(default_factory=list, description="the trial's own statements")
    virtual_s: float | None = Field(None, description="sum of their planned durations: the virtual robot's time, s")
    total_s: float | None = Field(None, description="the operator starting the trial -> the last final report, s")
    robot_total_s: float | None = Field(None, description="the operator starting -> the telerobot done with the last, s")
    alarms: int = Field(0, description="error reports from the telerobot (statements that failed)")
    one_way_delay_s: float | None = None


class ModeSummary(_Model):
    kind: str
    mode: str
    runs: int
    reached: int
    succeeded: int
    success_rate: float | None
    success_wilson95: tuple[float, float] | None
    total_s: float | None = Field(description="median over the successful runs, s")
    total_iqr_s: tuple[float, float] | None
    alarms: int
    thesis_success_rate: float | None
    failures: dict[str, int] = Field(description="how often each failure happened (numbers stripped)")


class KindSummary(_Model):
    kind: str
    clock: Literal["real", "virtual"]
    delay_ms: float
    seed: int
    cell: str
    world: dict[str, object]
    modes: list[ModeSummary]
    runs: list[KindRun]


class KindReport(_Model):
    summary: KindSummary


def _failure_key(text: str) -> str:
    """A failure without its numbers, so the same cause counts once."""
    import re

    return re.sub(r"-?\d+(\.\d+)?", "#", text)[:160]


def summarize_mode(kind: str, mode: str, runs: list[KindRun]) -> ModeSummary:
    reached = [r for r in runs if r.reached]
    good = [r for r in reached if r.success]
    times = [r.total_s for r in good if r.total_s is not None]
    failures: dict[str, int] = {}
    for r in runs:
        if not r.success and r.failure:
            key = _failure_key(r.failure)
            failures[key] = failures.get(key, 0) + 1
    interval = wilson_interval(len(good), len(reached))
    return ModeSummary(
        kind=kind, mode=mode, runs=len(runs), reached=len(reached), succeeded=len(good),
        success_rate=round(len(good) / len(reached), 4) if reached else None,
        success_wilson95=None if interval is None else (round(interval[0], 4), round(interval[1], 4)),
        total_s=med(times), total_iqr_s=iqr(times), alarms=sum(r.alarms for r in runs),
        thesis_success_rate=THESIS_SUCCESS.get((kind, mode)), failures=failures,
    )


def summarize_kind(kind: str, modes: tuple[str, ...], runs: list[KindRun], *, clock: str, delay_ms: float, seed: int,
                   cell: str, world: dict[str, object]) -> KindSummary:
    ordered = sorted(runs, key=lambda r: (modes.index(r.mode), r.index))
    return KindSummary(
        kind=kind, clock=clock, delay_ms=delay_ms, seed=seed, cell=cell, world=world,
        modes=[summarize_mode(kind, m, [r for r in ordered if r.mode == m]) for m in modes], runs=ordered,
    )
