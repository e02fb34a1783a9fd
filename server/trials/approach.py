"""The approach trial of thesis §4.6, online teleprogramming against step by step, through the
console's HTTP API of a real session (``server.trials.session``).

- **online**: the scripted operator drives the virtual robot through the approach; a statement
  is generated when the virtual robot finishes its stroke (the virtual robot's time is the
  statements' planned durations) and is submitted at once, without waiting for any report.
- **step by step**: each statement is submitted only once the previous one's final report came
  back through the link.

Between the modes the arm goes back to where the approach starts (untimed), so both modes run
the same motion from the same pose. The console is in the free regime (it streams submissions).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from robot_sim.settings import WorldSettings
from server.trials.drivers import Clock, Driver, SentRecord
from server.trials.open import open_driver
from server.trials.results import ModeResult, RunResult, StatementTiming
from server.trials.script import ApproachScript
from server.trials.session import TrialError


def _wait_timeout(script: ApproachScript, delay_s: float) -> float:
    return 2 * delay_s + 10 * script.virtual_s + 30.0


def _mode_result(mode, script: ApproachScript, items: list[SentRecord], one_way_s: float) -> ModeResult:
    rows = []
    for i, s in enumerate(items):
        fin = s.finished_at
        robot_done = fin - one_way_s if fin is not None else None
        rows.append(StatementTiming(
            index=i, text=s.text, planned_s=s.planned_s if s.planned_s else script.statements[i].planned_s,
            status=s.status, reason=s.reason, submitted_at=s.submitted_at, finished_at=fin,
            statement_s=None if fin is None else fin - s.submitted_at, run_s=s.run_s, robot_run_s=s.robot_run_s,
            robot_done_at=robot_done, lag_s=None if robot_done is None else robot_done - s.submitted_at,
        ))
    bad = next((r for r in rows if r.status != "done"), None)
    first, last = rows[0], rows[-1]
    reported = last.finished_at - first.submitted_at if last.finished_at is not None else None
    robot_total = last.robot_done_at - first.submitted_at if last.robot_done_at is not None else None
    runs = [r.run_s for r in rows if r.run_s is not None]
    to_report = [r.statement_s for r in rows if r.statement_s is not None]
    return ModeResult(
        mode=mode, statements=rows, virtual_s=sum(r.planned_s for r in rows),
        total_s=robot_total if mode == "online" else reported, reported_total_s=reported, robot_total_s=robot_total,
        mean_statement_s=sum(runs) / len(runs) if runs else None,
        mean_submit_to_report_s=sum(to_report) / len(to_report) if to_report else None,
        lag_s=last.lag_s, success=bad is None,
        failure=None if bad is None else f"statement {bad.index + 1} ({bad.text}) {bad.status}: {bad.reason or 'no reason given'}",
    )


def run_online(driver: Driver, script: ApproachScript, delay_s: float) -> list[SentRecord]:
    """Submit each statement when the virtual robot finishes it; then wait for every final report."""
    records: list[SentRecord] = []
    start = driver.now()
    generated_at = 0.0
    for stmt in script.statements:
        generated_at += stmt.planned_s
        driver.wait_until(start + generated_at)
        driver.generate([stmt.text])
        records += driver.send()
    return driver.finals(records, _wait_timeout(script, delay_s))


def run_step_by_step(driver: Driver, script: ApproachScript, delay_s: float) -> list[SentRecord]:
    """Submit each statement after the previous one's final report came back."""
    records: list[SentRecord] = []
    for stmt in script.statements:
        driver.generate([stmt.text])
        records += driver.finals(driver.send(), _wait_timeout(script, delay_s))
        if records[-1].status != "done":
            break
    return records


def run_one(script: ApproachScript, *, index: int, world: WorldSettings, delay_ms: float, log_dir: Path,
            clock: Clock = "real", on_mode: Callable[[str], None] = lambda mode: None) -> RunResult:
    """One run: a fresh session, the online mode, back to the start, the step-by-step mode."""
    delay_s = delay_ms / 1e3
    modes: dict[str, ModeResult] = {}
    one_way: float | None = None
    try:
        with open_driver(clock, cell=script.cell, delay_ms=delay_ms, world=world,
                         log_path=log_dir / f"run{index}.log") as driver:
            for mode, runner in (("online", run_online), ("step_by_step", run_step_by_step)):
                if mode != "online":
                    driver.restart_at_start(script.back_to_start)
                items = runner(driver, script, delay_s)
                one_way = driver.one_way_delay_s()
                modes[mode] = _mode_result(mode, script, items, one_way)
                on_mode(mode)
                if not modes[mode].success:
                    break
    except TrialError as exc:
        failure = str(exc)
    else:
        failure = next((f"{m}: {r.failure}" for m, r in modes.items() if not r.success), None)
        if failure is None and len(modes) < 2:
            failure = "the run stopped before both modes"
    return RunResult(index=index, world_seed=world.seed, delay_ms=delay_ms, clock=clock, one_way_delay_s=one_way,
                     online=modes.get("online"), step_by_step=modes.get("step_by_step"),
                     success=failure is None, failure=failure)
