"""The trial tables' statistics on hand-made runs: a step's success rate is over the runs that
reached that step (the thesis's rate of the step itself), never over every run."""

from __future__ import annotations

import pytest

from server.trials.kind_results import KindRun, summarize_mode
from server.trials.stats import wilson_interval


def run(index: int, *, reached: bool, success: bool, total_s: float | None = None, failure: str | None = None) -> KindRun:
    return KindRun(kind="insert", mode="supervised", index=index, world_seed=index, delay_ms=3000.0, clock="virtual",
                   reached=reached, success=success, failure=failure, total_s=total_s, alarms=int(not success))


def test_the_success_rate_is_over_the_runs_that_reached_the_step() -> None:
    """Five runs: three reached the insertion and two of those succeeded; two never reached it
    (their setup failed). The rate is 2 of 3, its interval Wilson's for 2 of 3; the runs that did
    not reach the step are counted and their failures listed, but not in the rate."""
    runs = [
        run(0, reached=True, success=True, total_s=10.0),
        run(1, reached=True, success=False, failure="statement 3 failed: stuck at 12.5 mm"),
        run(2, reached=False, success=False, failure="setup: the peg stuck at 4.0 mm"),
        run(3, reached=True, success=True, total_s=12.0),
        run(4, reached=False, success=False, failure="setup: the peg stuck at 7.5 mm"),
    ]
    mode = summarize_mode("insert", "supervised", runs)
    assert (mode.runs, mode.reached, mode.succeeded) == (5, 3, 2)
    assert mode.success_rate == pytest.approx(2 / 3, abs=1e-4)
    low, high = wilson_interval(2, 3)
    assert mode.success_wilson95 == (pytest.approx(low, abs=1e-4), pytest.approx(high, abs=1e-4))
    assert mode.total_s == 11.0 and mode.total_iqr_s == (10.5, 11.5)  # the successful runs' times
    assert mode.failures == {"setup: the peg stuck at # mm": 2, "statement # failed: stuck at # mm": 1}
    assert mode.thesis_success_rate == 0.90


def test_no_run_that_reached_the_step_leaves_the_rate_empty() -> None:
    mode = summarize_mode("insert", "supervised", [run(0, reached=False, success=False, failure="setup: stuck")])
    assert (mode.runs, mode.reached, mode.succeeded) == (1, 0, 0)
    assert mode.success_rate is None and mode.success_wilson95 is None
