"""The silence watch (shared.wire.liveness), stated exactly: pinned by its mutation run (issue 38)."""

from __future__ import annotations

import pytest

from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S, HEARTBEAT_INTERVAL_S, SilenceWatch


def test_nothing_is_silent_before_the_first_arrival():
    watch = SilenceWatch()
    assert watch.armed is False
    assert watch.age(100.0) is None
    assert watch.silent(100.0) is False


def test_the_threshold_is_the_expected_gap_plus_the_limit():
    assert SilenceWatch().threshold == pytest.approx(HEARTBEAT_INTERVAL_S + DEFAULT_SILENCE_LIMIT_S)
    assert SilenceWatch(interval=0.5, limit=2.0).threshold == pytest.approx(2.5)


def test_the_age_is_the_time_since_the_last_arrival_and_never_negative():
    watch = SilenceWatch()
    watch.heard(10.0)
    assert watch.armed is True
    assert watch.last_heard == 10.0
    assert watch.age(10.75) == pytest.approx(0.75)
    watch.heard(11.0)
    assert watch.age(11.25) == pytest.approx(0.25)
    # a clock read before the arrival was stamped (another thread's time) gives age 0, not negative
    assert watch.age(9.0) == 0.0


def test_silent_only_strictly_beyond_the_threshold():
    watch = SilenceWatch(interval=0.25, limit=1.0)
    watch.heard(4.0)
    assert watch.silent(4.0) is False
    assert watch.silent(5.25) is False  # exactly the threshold: not yet silent
    assert watch.silent(5.2500001) is True
    watch.heard(5.5)  # an arrival ends the silence
    assert watch.silent(5.6) is False


def test_a_reset_forgets_the_other_end():
    watch = SilenceWatch()
    watch.heard(1.0)
    assert watch.silent(50.0) is True
    watch.reset()
    assert watch.armed is False
    assert watch.last_heard is None
    assert watch.age(50.0) is None
    assert watch.silent(50.0) is False
