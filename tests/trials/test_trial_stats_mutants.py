"""The trial tables' statistics, stated with figures computed by hand or from the literature:
pinned by the mutation run of server/trials/stats.py and kind_results.py (issue 38)."""

from __future__ import annotations

import pytest

from server.trials.kind_results import THESIS_SUCCESS, KindRun, _failure_key, summarize_kind, summarize_mode
from server.trials.stats import Z95, iqr, med, wilson_interval


def run(index: int, *, mode: str = "supervised", reached: bool = True, success: bool = True, total_s: float | None = None,
        failure: str | None = None, alarms: int = 0) -> KindRun:
    return KindRun(kind="insert", mode=mode, index=index, world_seed=index, delay_ms=3000.0, clock="virtual",
                   reached=reached, success=success, failure=failure, total_s=total_s, alarms=alarms)


def test_z95_is_the_standard_normals_97_5_percent_point():
    assert Z95 == pytest.approx(1.959964, abs=1e-6)


@pytest.mark.parametrize(("successes", "n", "low", "high"), [
    (8, 10, 0.4902, 0.9433),  # the textbook example (Wilson 1927; Newcombe 1998)
    (0, 20, 0.0, 0.1611),
    (20, 20, 0.8389, 1.0),
    (2, 3, 0.2077, 0.9385),
    (1, 1, 0.2065, 1.0),
])
def test_the_wilson_interval_at_95_percent(successes, n, low, high):
    got = wilson_interval(successes, n)
    assert got == (pytest.approx(low, abs=1e-4), pytest.approx(high, abs=1e-4))


def test_the_wilson_interval_with_another_z_by_hand():
    # p = 0.3, z = 1: centre = (0.3 + 1/20) / 1.1, half = sqrt(0.021 + 1/400) / 1.1
    centre, half = 0.35 / 1.1, (0.021 + 0.0025) ** 0.5 / 1.1
    assert wilson_interval(3, 10, z=1.0) == (pytest.approx(centre - half, abs=1e-12), pytest.approx(centre + half, abs=1e-12))


def test_the_wilson_interval_stays_within_zero_and_one_exactly():
    assert wilson_interval(0, 5)[0] == 0.0
    assert wilson_interval(5, 5)[1] == 1.0
    # where the formula's rounding lands just outside [0, 1] (16 of 16 above one, 0 of 21 below
    # zero by an ulp), the interval is clipped to exactly 1 and 0
    assert wilson_interval(16, 16)[1] == 1.0
    assert wilson_interval(0, 21)[0] == 0.0


def test_no_runs_have_no_interval_and_impossible_counts_are_refused():
    assert wilson_interval(0, 0) is None
    assert wilson_interval(0, -1) is None
    assert wilson_interval(1, 1) is not None
    for bad in (-1, 4):
        with pytest.raises(ValueError) as err:
            wilson_interval(bad, 3)
        assert str(err.value) == f"successes must be within 0..3; got {bad}"


def test_the_median_is_rounded_to_four_decimals():
    assert med([]) is None
    assert med([0.123456]) == 0.1235
    assert med([1.0, 2.0, 3.0, 4.00001]) == 2.5
    assert med([3.0, 1.0, 2.0]) == 2.0


def test_the_quartiles_are_the_inclusive_ones_rounded():
    assert iqr([]) is None
    assert iqr([1.23456]) == (1.2346, 1.2346)
    assert iqr([1.0, 2.0, 3.0, 4.0]) == (1.75, 3.25)  # the exclusive method gives (1.25, 3.75)
    assert iqr([1.0, 2.0, 3.0, 4.0, 5.0]) == (2.0, 4.0)
    assert iqr([1.23456, 2.0]) == (1.4259, 1.8086)


def test_a_failure_is_counted_without_its_numbers():
    assert _failure_key("the peg stuck at -1.5 mm after 22 s, try 3.") == "the peg stuck at # mm after # s, try #."
    assert _failure_key("x" * 200) == "x" * 160


def test_a_mode_summary_counts_rounds_and_lists_failures():
    runs = [
        run(0, total_s=10.0, alarms=0),
        run(1, total_s=14.0, alarms=2),
        run(2, success=False, failure="stuck at 1.5 mm", alarms=1),
        run(3, reached=False, success=False, failure="setup: stuck at 2 mm", alarms=3),
        run(4, total_s=None),  # a success without a time: counted, not timed
        run(5, success=False, failure=None),  # a failure without words: counted, not listed
        run(6, success=True, failure="a note on a success"),  # never listed as a failure
    ]
    mode = summarize_mode("insert", "supervised", runs)
    assert (mode.kind, mode.mode, mode.runs, mode.reached, mode.succeeded) == ("insert", "supervised", 7, 6, 4)
    assert mode.success_rate == 0.6667  # 4 of 6, rounded to four decimals
    low, high = wilson_interval(4, 6)
    assert mode.success_wilson95 == (round(low, 4), round(high, 4))
    assert mode.total_s == 12.0
    assert mode.total_iqr_s == (11.0, 13.0)
    assert mode.alarms == 6
    assert mode.thesis_success_rate == 0.90
    assert mode.failures == {"stuck at # mm": 1, "setup: stuck at # mm": 1}


def test_every_run_reaching_and_succeeding_gives_rate_one():
    mode = summarize_mode("grasp", "offline", [run(0, total_s=5.0), run(1, total_s=7.0)])
    assert (mode.success_rate, mode.succeeded) == (1.0, 2)
    assert mode.success_wilson95 == (0.3424, 1.0)
    assert mode.thesis_success_rate == THESIS_SUCCESS[("grasp", "offline")] == 1.0
    assert mode.failures == {}


def test_the_thesis_figures_and_a_mode_without_one():
    assert THESIS_SUCCESS == {("grasp", "offline"): 1.0, ("extract", "supervised"): 0.95,
                              ("insert", "supervised"): 0.9, ("transfer", "composite"): 1.0}
    assert summarize_mode("insert", "offline", [run(0)]).thesis_success_rate is None


def test_a_kind_summary_orders_runs_by_mode_then_index_and_summarises_each_mode():
    runs = [run(1, mode="b"), run(0, mode="b", success=False, failure="f"), run(2, mode="a"), run(0, mode="a")]
    summary = summarize_kind("insert", ("a", "b"), runs, clock="virtual", delay_ms=3000.0, seed=7, cell="c.toml",
                             world={"w": 1})
    assert [(r.mode, r.index) for r in summary.runs] == [("a", 0), ("a", 2), ("b", 0), ("b", 1)]
    assert [(m.mode, m.runs, m.succeeded) for m in summary.modes] == [("a", 2, 2), ("b", 2, 1)]
    assert (summary.kind, summary.clock, summary.delay_ms, summary.seed, summary.cell, summary.world) == (
        "insert", "virtual", 3000.0, 7, "c.toml", {"w": 1})
