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

import time
from collections.abc import Callable
from pathlib import Path

from server.trials.results import ApproachReport, ModeResult, RunResult, StatementTiming, summarize
from server.trials.script import ApproachScript
from server.trials.session import ConsoleApi, TrialError, TrialSession, wait_until

FINAL = {"done", "failed", "skipped", "aborted", "rejected", "unknown"}
POLL_S = 0.02  # how often the client reads /api/sent while it waits for a report


def _insert_and_submit(api: ConsoleApi, text: str) -> tuple[int, float | None]:
    """Put ``text`` in the (empty) program and submit it; its console id and planned duration."""
    program = api.call("POST", "/api/program/insert", {"text": text})
    planned = program["entries"][0]["duration_s"]
    sent = api.call("POST", "/api/submit", {"start": 0, "stop": 1})
    return sent["items"][-1]["id"], planned


def _final_items(api: ConsoleApi, ids: list[int], timeout: float) -> list[dict]:
    def finals():
        items = {s["id"]: s for s in api.call("GET", "/api/sent")["items"]}
        mine = [items.get(i) for i in ids]
        return mine if all(s is not None and s["status"] in FINAL for s in mine) else None

    return wait_until(finals, timeout, f"final reports of statements {ids}", POLL_S)


def _wait_timeout(script: ApproachScript, delay_s: float) -> float:
    return 2 * delay_s + 10 * script.virtual_s + 30.0


def _mode_result(mode, script: ApproachScript, items: list[dict], planned: list[float | None],
                 one_way_s: float) -> ModeResult:
    rows = []
    for i, (s, p) in enumerate(zip(items, planned, strict=True)):
        fin = s["finished_at"]
        robot_done = fin - one_way_s if fin is not None else None
        rows.append(StatementTiming(
            index=i, text=s["text"], planned_s=p if p is not None else script.statements[i].planned_s,
            status=s["status"], reason=s["reason"], submitted_at=s["submitted_at"], finished_at=fin,
            statement_s=None if fin is None else fin - s["submitted_at"], run_s=s["run_s"], robot_done_at=robot_done,
            lag_s=None if robot_done is None else robot_done - s["submitted_at"],
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


def run_online(api: ConsoleApi, script: ApproachScript, delay_s: float) -> tuple[list[dict], list[float | None]]:
    """Submit each statement when the virtual robot finishes it; then wait for every final report."""
    ids, planned = [], []
    start = time.monotonic()
    generated_at = 0.0
    for stmt in script.statements:
        generated_at += stmt.planned_s
        time.sleep(max(0.0, start + generated_at - time.monotonic()))
        sid, p = _insert_and_submit(api, stmt.text)
        ids.append(sid)
        planned.append(p)
    return _final_items(api, ids, _wait_timeout(script, delay_s)), planned


def run_step_by_step(api: ConsoleApi, script: ApproachScript, delay_s: float) -> tuple[list[dict], list[float | None]]:
    """Submit each statement after the previous one's final report came back."""
    items, planned = [], []
    for stmt in script.statements:
        sid, p = _insert_and_submit(api, stmt.text)
        planned.append(p)
        items.extend(_final_items(api, [sid], _wait_timeout(script, delay_s)))
        if items[-1]["status"] != "done":
            break
    return items, planned


def _back_to_start(api: ConsoleApi, script: ApproachScript, delay_s: float) -> None:
    """Take the arm back to the approach's start (untimed) and make sure the model agrees."""
    sid, _ = _insert_and_submit(api, script.back_to_start)
    (item,) = _final_items(api, [sid], _wait_timeout(script, delay_s))
    if item["status"] != "done":
        raise TrialError(f"going back to the approach's start: {item['status']}: {item['reason']}")
    wait_until(lambda: api.call("GET", "/api/remote")["state"] == "idle", 10.0 + 2 * delay_s, "the telerobot idle")
    if api.call("GET", "/api/divergence")["diverged"]:
        api.call("POST", "/api/resync")


def run_one(script: ApproachScript, *, index: int, world_seed: int, delay_ms: float, log_dir: Path,
            on_mode: Callable[[str], None] = lambda mode: None) -> RunResult:
    """One run: a fresh session, the online mode, back to the start, the step-by-step mode."""
    delay_s = delay_ms / 1e3
    modes: dict[str, ModeResult] = {}
    one_way: float | None = None
    try:
        with TrialSession(delay_ms=delay_ms, cell=script.cell, world_seed=world_seed,
                          log_path=log_dir / f"run{index}.log") as session:
            api = session.api
            api.take_control()
            api.call("PUT", "/api/regime", {"regime": "free"})
            api.call("PUT", "/api/program/auto", {"on": False})
            for mode, runner in (("online", run_online), ("step_by_step", run_step_by_step)):
                if mode != "online":
                    _back_to_start(api, script, delay_s)
                items, planned = runner(api, script, delay_s)
                measured = api.call("GET", "/api/link")["delay_s"]
                one_way = measured if measured is not None else delay_s
                modes[mode] = _mode_result(mode, script, items, planned, one_way)
                on_mode(mode)
                if not modes[mode].success:
                    break
    except TrialError as exc:
        failure = str(exc)
    else:
        failure = next((f"{m}: {r.failure}" for m, r in modes.items() if not r.success), None)
        if failure is None and len(modes) < 2:
            failure = "the run stopped before both modes"
    return RunResult(index=index, world_seed=world_seed, delay_ms=delay_ms, one_way_delay_s=one_way,
                     online=modes.get("online"), step_by_step=modes.get("step_by_step"),
                     success=failure is None, failure=failure)


def world_seed(seed: int, index: int) -> int:
    """The seed of run ``index``'s world: repeatable alone, different for every run of a batch."""
    return seed * 1000 + index


def run_batch(script: ApproachScript, *, runs: int, delay_ms: float, seed: int, log_dir: Path,
              on_mode: Callable[[str], None] = lambda mode: None,
              on_run: Callable[[RunResult], None] = lambda run: None) -> ApproachReport:
    """``runs`` independent runs, one after the other, and their summary; ``on_mode`` is called
    after each mode that ran, ``on_run`` after each run (a progress bar)."""
    results = []
    for i in range(runs):
        results.append(run_one(script, index=i, world_seed=world_seed(seed, i), delay_ms=delay_ms, log_dir=log_dir,
                               on_mode=on_mode))
        on_run(results[-1])
    return ApproachReport(summary=summarize(results, delay_ms=delay_ms, seed=seed, cell=script.cell,
                                            statements=len(script.statements)))
