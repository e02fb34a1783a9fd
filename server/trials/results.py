"""The approach trial's results as typed models: per statement, per mode, per run, and the
summary over runs with the thesis's figures beside ours.

Times are the console's clock (Unix seconds, the same host's clock for every process of a
session): ``submitted_at`` when the console took the statement, ``finished_at`` when its final
report arrived through the link. What they mean:

- statement time: submit -> final report (a round trip of the link plus the robot's run);
- run time (``run_s``): the running report -> the final report, i.e. the telerobot's execution
  of the statement (both reports cross the link with the same delay);
- the telerobot done with a statement: its final report's arrival less the link's measured
  one-way delay;
- lag behind the virtual robot: the virtual robot has finished a statement when it is generated
  and submitted, so the lag is telerobot done - submitted;
- online total (the thesis's "总用时"): first submit -> the telerobot done with the last
  statement; the last report reaches the console one delay later (``reported_total_s``);
- step-by-step total: first submit -> the last final report (the next statement waits for it).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from server.trials.stats import iqr, med

Mode = Literal["online", "step_by_step"]
THESIS_DELAY_MS = 3000.0
THESIS_ONLINE_S = 7.0  # §4.6: the virtual robot about 4 s, the telerobot about 3 s later
THESIS_STEP_BY_STEP_S = 28.0  # §4.6: (3 + 1 + 3) x 4, estimated


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True)


class StatementTiming(_Model):
    index: int = Field(description="0-based place in the trial's statements")
    text: str
    planned_s: float = Field(description="planned duration (the console's planner), s")
    status: str = Field(description="final status from the telerobot, or the last one seen")
    reason: str | None = None
    submitted_at: float = Field(description="console clock (Unix s) when the console took the statement")
    finished_at: float | None = Field(None, description="console clock when the final report arrived")
    statement_s: float | None = Field(None, description="submit -> final report, s")
    run_s: float | None = Field(None, description="running report -> final report: the telerobot's execution, s")
    robot_run_s: float | None = Field(None, description="running -> final on the robot's own clock, s")
    robot_done_at: float | None = Field(None, description="final report's arrival less the one-way delay")
    lag_s: float | None = Field(None, description="telerobot done - submitted (the virtual robot done), s")


class ModeResult(_Model):
    mode: Mode
    statements: list[StatementTiming]
    virtual_s: float = Field(description="sum of the planned durations: the virtual robot's time, s")
    total_s: float | None = Field(None, description="the mode's total: online to the telerobot done, step by step to the last report")
    reported_total_s: float | None = Field(None, description="first submit -> last final report, s")
    robot_total_s: float | None = Field(None, description="first submit -> the telerobot done with the last statement, s")
    mean_statement_s: float | None = Field(None, description="mean telerobot run time of a statement, s")
    mean_submit_to_report_s: float | None = Field(None, description="mean submit -> final report, s")
    lag_s: float | None = Field(None, description="the telerobot's lag behind the virtual robot at the last statement, s")
    success: bool
    failure: str | None = None


class RunResult(_Model):
    index: int
    world_seed: int
    delay_ms: float
    clock: Literal["real", "virtual"] = "real"
    one_way_delay_s: float | None = Field(None, description="the link's one-way delay as the console measured it, s")
    online: ModeResult | None = None
    step_by_step: ModeResult | None = None
    success: bool
    failure: str | None = None


class ApproachSummary(_Model):
    kind: Literal["approach"] = "approach"
    clock: Literal["real", "virtual"] = "real"
    runs_total: int
    runs_succeeded: int
    delay_ms: float
    seed: int
    cell: str
    world: dict[str, object] = Field(default_factory=dict, description="the worlds' engine and settings (each run's seed aside)")
    statements: int
    virtual_s: float | None
    mean_statement_s: float | None = Field(description="median over runs of the mean telerobot run time, s")
    online_total_s: float | None
    online_total_iqr_s: tuple[float, float] | None
    online_reported_total_s: float | None
    online_lag_s: float | None
    step_by_step_total_s: float | None
    step_by_step_total_iqr_s: tuple[float, float] | None
    predicted_online_s: float | None = Field(description="virtual time + one-way delay")
    predicted_step_by_step_s: float | None = Field(description="n x (2 x delay + mean statement time)")
    ratio: float | None = Field(description="step_by_step_total_s / online_total_s")
    thesis: dict[str, float] = Field(description="§4.6's figures at a 3 s delay")
    runs: list[RunResult]


class ApproachReport(_Model):
    summary: ApproachSummary


_med, _iqr = med, iqr


def summarize(runs: list[RunResult], *, delay_ms: float, seed: int, cell: str, statements: int,
              clock: str = "real", world: dict[str, object] | None = None) -> ApproachSummary:
    """Medians over the runs whose both modes succeeded, and the predictions from them."""
    good = [r for r in runs if r.success and r.online is not None and r.step_by_step is not None]
    online = [r.online.total_s for r in good if r.online.total_s is not None]
    step = [r.step_by_step.total_s for r in good if r.step_by_step.total_s is not None]
    means = [m for r in good for m in (r.online.mean_statement_s, r.step_by_step.mean_statement_s) if m is not None]
    virtual = _med([r.online.virtual_s for r in good])
    mean_statement = _med(means)
    d = delay_ms / 1e3
    online_med, step_med = _med(online), _med(step)
    return ApproachSummary(
        clock=clock, world=world or {},
        runs_total=len(runs), runs_succeeded=len(good), delay_ms=delay_ms, seed=seed, cell=cell, statements=statements,
        virtual_s=virtual, mean_statement_s=mean_statement,
        online_total_s=online_med, online_total_iqr_s=_iqr(online),
        online_reported_total_s=_med([r.online.reported_total_s for r in good if r.online.reported_total_s is not None]),
        online_lag_s=_med([r.online.lag_s for r in good if r.online.lag_s is not None]),
        step_by_step_total_s=step_med, step_by_step_total_iqr_s=_iqr(step),
        predicted_online_s=None if virtual is None else round(virtual + d, 4),
        predicted_step_by_step_s=None if mean_statement is None else round(statements * (2 * d + mean_statement), 4),
        ratio=round(step_med / online_med, 3) if online_med and step_med else None,
        thesis={"delay_ms": THESIS_DELAY_MS, "online_total_s": THESIS_ONLINE_S,
                "step_by_step_total_s": THESIS_STEP_BY_STEP_S, "ratio": THESIS_STEP_BY_STEP_S / THESIS_ONLINE_S},
        runs=runs,
    )
