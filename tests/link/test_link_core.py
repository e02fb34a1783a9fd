"""The delay core in virtual time: delay, jitter without reordering, bandwidth queueing, faults."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from shared.link.core import Delivery, Direction, LinkCore, LinkFault, LinkParams

UP, DOWN = Direction.UP, Direction.DOWN


def run(core: LinkCore, sends: list[tuple[float, Direction, bytes]], until: float) -> list[Delivery | LinkFault]:
    """Feed sends at their times and poll at every due time, as the relay does."""
    out: list = []
    sends = sorted(sends, key=lambda s: s[0])
    i, now = 0, 0.0
    while True:
        nxt = core.next_due()
        t_send = sends[i][0] if i < len(sends) else None
        candidates = [t for t in (nxt, t_send) if t is not None]
        if not candidates or min(candidates) > until:
            return out
        now = min(candidates)
        while i < len(sends) and sends[i][0] <= now:
            core.send(sends[i][0], sends[i][1], sends[i][2])
            i += 1
        out += core.poll(now)


def test_default_is_three_seconds_each_way():
    assert LinkParams().delay_s == 3.0
    core = LinkCore()
    core.send(10.0, UP, b"cmd")
    assert core.poll(12.999) == []
    (d,) = core.poll(13.0)
    assert (d.direction, d.payload, d.sent_at, d.due_at) == (UP, b"cmd", 10.0, 13.0)


def test_directions_are_independent_and_polled_in_due_order():
    core = LinkCore(LinkParams(delay_s=1.0))
    core.send(0.0, UP, b"a")
    core.send(0.5, DOWN, b"b")
    core.send(0.6, UP, b"c")
    assert [(d.direction, d.payload) for d in core.poll(5.0)] == [(UP, b"a"), (DOWN, b"b"), (UP, b"c")]


@given(
    times=st.lists(st.floats(min_value=0, max_value=10, allow_nan=False), min_size=1, max_size=60),
    jitter=st.floats(min_value=0, max_value=2.0),
    seed=st.integers(min_value=0, max_value=2**32),
)
@settings(max_examples=200, deadline=None)
def test_jitter_never_reorders_and_never_undercuts_the_delay(times, jitter, seed):
    params = LinkParams(delay_s=0.5, jitter_s=jitter, seed=seed)
    core = LinkCore(params)
    sends = [(t, UP, i.to_bytes(4, "little")) for i, t in enumerate(sorted(times))]
    out = run(core, sends, until=1e9)
    assert [int.from_bytes(d.payload, "little") for d in out] == list(range(len(times)))
    assert [d.index for d in out] == list(range(len(times)))
    for d in out:
        assert d.due_at >= d.sent_at + params.delay_s
    dues = [d.due_at for d in out]
    assert dues == sorted(dues)
    # without reordering, a message is late only because of its own draw or the one ahead of it
    for prev, d in zip(out, out[1:]):
        assert d.due_at <= max(d.sent_at + params.delay_s + jitter, prev.due_at) + 1e-9


def test_jitter_is_seeded_and_spread():
    def dues(seed):
        core = LinkCore(LinkParams(delay_s=1.0, jitter_s=0.1, seed=seed))
        return [core.send(float(t), UP, b"x") for t in range(200)]

    assert dues(3) == dues(3)
    assert dues(3) != dues(4)
    extra = np.array(dues(3)) - np.arange(200) - 1.0
    assert extra.min() >= 0 and extra.max() <= 0.1 and extra.std() > 0.02


def test_bandwidth_queues_a_burst():
    # 1,000 bytes/s: ten 100-byte messages sent together take 0.1 s each to transmit
    core = LinkCore(LinkParams(delay_s=2.0, bandwidth_bytes_per_s=1000.0))
    dues = [core.send(0.0, UP, bytes(100)) for _ in range(10)]
    assert dues == pytest.approx([2.0 + 0.1 * (k + 1) for k in range(10)])
    assert core.queued_bytes(UP) == 1000
    # the other direction has its own line
    assert core.send(0.0, DOWN, bytes(100)) == pytest.approx(2.1)
    # once the line is idle again, a message waits only for itself
    assert core.send(50.0, UP, bytes(10)) == pytest.approx(52.01)


def test_telemetry_at_50_hz_fits_a_slow_line_without_growing_delay():
    # 174-byte frames at 50 Hz are 8,700 bytes/s; a 10 kB/s line carries them with constant delay
    core = LinkCore(LinkParams(delay_s=3.0, bandwidth_bytes_per_s=10_000.0))
    dues = np.array([core.send(k / 50, DOWN, bytes(174)) for k in range(500)])
    lag = dues - np.arange(500) / 50
    assert lag.max() - lag.min() < 1e-9 and lag[0] == pytest.approx(3.0174)
    # at 5 kB/s the queue grows without bound: each frame later than the one before
    slow = LinkCore(LinkParams(delay_s=3.0, bandwidth_bytes_per_s=5_000.0))
    lag = np.array([slow.send(k / 50, DOWN, bytes(174)) for k in range(500)]) - np.arange(500) / 50
    assert np.all(np.diff(lag) > 0)


def test_str_payloads_count_their_utf8_bytes():
    core = LinkCore(LinkParams(delay_s=0.0, bandwidth_bytes_per_s=10.0))
    assert core.send(0.0, UP, "é" * 5) == pytest.approx(1.0)


def test_a_loss_cuts_the_connection_and_starts_an_outage():
    params = LinkParams(delay_s=1.0, drop_probability=0.2, outage_s=5.0, seed=11)
    core = LinkCore(params)
    sends = [(k * 0.1, UP if k % 2 else DOWN, bytes([k])) for k in range(100)]
    out = run(core, sends, until=1e9)
    first = next(i for i, e in enumerate(out) if isinstance(e, LinkFault))
    fault = out[first]
    assert fault.up_at == pytest.approx(fault.at + 5.0) and fault.lost >= 1
    assert all(d.due_at <= fault.at for d in out[:first])
    # what was in flight is gone; what was sent during the outage never entered
    after = [e for e in out[first + 1 :] if isinstance(e, Delivery)]
    assert all(d.sent_at >= fault.up_at for d in after)


def test_nothing_enters_during_an_outage():
    core = LinkCore(LinkParams(delay_s=1.0, drop_probability=0.999, outage_s=5.0))
    core.send(0.0, UP, b"lost")
    (fault,) = core.poll(0.0)
    assert isinstance(fault, LinkFault) and core.in_flight() == 0
    assert core.send(1.0, UP, b"late") is None and core.in_flight() == 0
    assert not core.available(4.9) and core.available(5.0)


def test_losses_follow_the_probability():
    core = LinkCore(LinkParams(delay_s=0.0, drop_probability=0.05, outage_s=0.0, seed=2))
    faults = 0
    for k in range(4000):
        core.send(float(k), UP, b"x")
        faults += sum(isinstance(e, LinkFault) for e in core.poll(float(k)))
    assert 120 < faults < 280  # 200 expected


def test_no_loss_without_drop_probability():
    core = LinkCore(LinkParams(delay_s=0.01))
    out = run(core, [(k * 0.001, UP, b"x") for k in range(5000)], until=1e9)
    assert len(out) == 5000 and all(isinstance(d, Delivery) for d in out)


def test_cut_discards_in_flight():
    core = LinkCore(LinkParams(delay_s=1.0))
    core.send(0.0, UP, b"a")
    core.send(0.0, DOWN, b"b")
    assert core.cut() == 2
    assert core.poll(10.0) == [] and core.next_due() is None


@pytest.mark.parametrize("bad", [{"delay_s": -1}, {"jitter_s": -0.1}, {"drop_probability": 1.0}, {"bandwidth_bytes_per_s": -5}, {"nope": 1}])
def test_params_are_validated(bad):
    with pytest.raises(ValidationError):
        LinkParams(**bad)
