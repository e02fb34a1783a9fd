"""Fault campaigns (``teleprog trial faults``): seeded faults, the link's faults, the judge's ground
truth (a robot with its safety turned off is caught missing), replays that repeat a run exactly,
and every miss found while building kept here as a regression case by its seed."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from robot_sim.executor import Executor
from server.trials.faults.campaign import (
    GROUP,
    CampaignRequest,
    group_specs,
    replay,
    run_campaign,
    run_group,
    run_seed,
    split_seed,
)
from server.trials.faults.catalogue import FAULT_KINDS, CleanTrace, draw_fault
from server.trials.faults.link import FaultyLink
from server.trials.faults.results import summarize
from shared.cells.loader import DEFAULT_CELL
from shared.link.core import Delivery, Direction, LinkCore, LinkParams

CELL = str(DEFAULT_CELL)


def _trace() -> CleanTrace:
    trace = CleanTrace(dt=0.01, start=6.0, end=60.0, last_task_start=50.0)
    for k in range(600, 6000, 10):
        trace.add(k * 0.01, (0.5, 0.0, 0.5), 0.05)
    return trace


def test_a_faults_draw_depends_on_its_seed_alone_and_strikes_within_the_program() -> None:
    trace = _trace()
    a = [draw_fault(np.random.default_rng(s), FAULT_KINDS, trace, 6, ["peg"]) for s in range(300)]
    b = [draw_fault(np.random.default_rng(s), FAULT_KINDS, trace, 6, ["peg"]) for s in range(300)]
    assert a == b
    assert {f.kind for f in a} == set(FAULT_KINDS)  # 300 draws meet every kind
    for f in a:
        assert 0.0 <= f.at_s <= trace.end - trace.start
        if f.kind in ("object_moved", "object_missing", "hole_moved"):
            assert f.at_s <= trace.last_task_start - trace.start  # before the last task, or it could never be found out
        if f.kind == "joint_drag":
            assert 0 <= f.joint < 6 and f.magnitude != 0.0


def test_a_run_seed_names_the_campaign_and_the_run() -> None:
    assert split_seed(run_seed(42, 7)) == (42, 7)
    specs = group_specs(CampaignRequest(runs=25, seed=3), CELL, range(25))
    assert [len(s.indices) for s in specs] == [GROUP, GROUP, 5] and specs[1].indices[0] == GROUP


def _deliveries(link: FaultyLink, t_end: float, dt: float = 0.01) -> list[tuple[float, Delivery]]:
    out, t = [], 0.0
    while t < t_end:
        out += [(t, d) for d in link.poll(t) if isinstance(d, Delivery)]
        t += dt
    return out


def test_a_stall_holds_both_ways_and_delivers_everything_after_it_in_order() -> None:
    link = FaultyLink(LinkCore(LinkParams(delay_s=0.5)), kind="stall", start=1.0, duration=2.0)
    for k in range(40):
        link.send(k * 0.1, Direction.UP, f"up{k}")
        link.send(k * 0.1, Direction.DOWN, f"down{k}")
    got = _deliveries(link, 10.0)
    assert [d.payload for _, d in got if d.direction is Direction.UP] == [f"up{k}" for k in range(40)]
    assert not [t for t, _ in got if 1.0 <= t < 3.0 - 1e-9]  # nothing arrives during the stall
    assert max(t for t, d in got if d.direction is Direction.UP) >= 3.0


def test_a_jitter_burst_delays_but_never_reorders() -> None:
    link = FaultyLink(LinkCore(LinkParams(delay_s=0.2)), kind="jitter", start=0.5, duration=2.0, extra=1.0, seed=3)
    for k in range(30):
        link.send(k * 0.1, Direction.UP, str(k))
    got = [(t, int(d.payload)) for t, d in _deliveries(link, 8.0)]
    assert [p for _, p in got] == list(range(30))
    late = [t - (p * 0.1 + 0.2) for t, p in got if 0.5 <= p * 0.1 < 2.5]
    assert max(late) > 0.2  # the burst really delayed some


def test_a_cut_loses_what_is_in_flight_and_calls_the_robot_and_the_console_back() -> None:
    calls: list[str] = []
    link = FaultyLink(LinkCore(LinkParams(delay_s=1.0)), kind="cut", start=0.5, duration=1.0,
                      on_cut=lambda: calls.append("cut"), on_reconnect=lambda: calls.append("back"))
    link.send(0.0, Direction.UP, "lost")
    link.poll(0.6)
    assert link.send(0.8, Direction.UP, "while down") is None
    link.poll(1.6)
    link.send(1.7, Direction.UP, "after")
    got = [d.payload for _, d in _deliveries(link, 4.0)]
    assert calls == ["cut", "back"] and got == ["after"]


def _run(seed: int, **request) -> object:
    return replay(CampaignRequest(**request), CELL, seed)


@pytest.mark.parametrize(("seed", "kind", "found"), [
    (3000003, "sensor_dropout", "a NaN reading broke the robot's status report (the wire refuses NaN)"),
    (4000029, "heavier", "a mass changed mid-run blew the physics up (now the world's from the start)"),
    (5000018, "obstacle", "the box appeared inside the arm (now it is never put where it touches)"),
    (3000009, "object_missing", "taken after the last task: the world wrong, nothing could find it"),
    (4000017, "console_frozen", "the console was silent before its freeze (a wrong window): a false stop"),
    (2026000181, "hole_moved", "the fingers struck a peg held fast by its moved hole with the whole grip (102 N)"),
    (2026000889, "sensor_bias", "the biased sensor ended the descent high; the closing fingers struck the peg (102 N)"),
    (2026000511, "joint_drag", "a drag in a guarded motion ran the arm 5.8 mm off its path unwatched"),
    (2027000056, "link_cut", "the virtual console took the robot's repeated acceptance of a re-sent communication for a new one"),
    (2028000976, "peg_slip", "the peg slid 27 mm up in the fingers; the tool reached the seat and the robot called it seated"),
    (2029000059, "peg_slip", "the peg fell out while the robot waited for its next statement: noticed 3.3 s later"),
])
def test_every_miss_found_while_building_stays_found(seed: int, kind: str, found: str) -> None:
    run = _run(seed)
    assert run.fault.kind == kind, f"the catalogue's draw changed: seed {seed} is now {run.fault.kind}"
    assert run.outcome in ("caught", "absorbed"), f"{found}: {run.outcome}: {run.why}"
    assert run.latency_ms is None or run.fault.kind.startswith(("link", "jitter", "console")) or run.latency_ms <= 100.0


@pytest.mark.xfail(strict=True, reason="known misses of the 4,000-run campaign, not fixed yet: when one is, move it above")
@pytest.mark.parametrize(("seed", "kind", "found"), [
    (2028000159, "joint_drag", "141 N m on joint 3: the PD servo, stopped, holds the arm on the plate with 131 N"),
    (2026000512, "jam", "the seating push overshoots the 80 N limit to 104 N"),
])
def test_the_misses_not_fixed_yet_are_still_missed(seed: int, kind: str, found: str) -> None:
    run = _run(seed)
    assert run.fault.kind == kind
    assert run.outcome != "missed", f"{found}: {run.why}"


def test_a_replayed_run_repeats_its_statuses_and_robot_times_exactly() -> None:
    first, again = _run(7000005), _run(7000005)
    assert first.fault.kind == "jam" and first.outcome == "caught"
    assert first.statements and first.statements == again.statements
    assert (first.stop_s, first.latency_ms, first.peak_load_n) == (again.stop_s, again.latency_ms, again.peak_load_n)


def test_the_judge_finds_a_miss_when_the_robots_safety_is_off(monkeypatch) -> None:
    """The same obstacle the robot catches (seed 5000016) harms the world once the robot neither
    watches its force nor its links: the judge reads it from the physics, not from the robot."""
    caught = _run(5000016)
    assert caught.fault.kind == "obstacle" and caught.outcome == "caught" and caught.latency_ms is not None
    original = Executor.__init__

    def reckless(self, *args, **kwargs) -> None:
        original(self, *args, **kwargs)
        self.settings = self.settings.model_copy(update={"contact_limit": 1e6, "max_force": 1e6, "collision_checks": False})

    monkeypatch.setattr(Executor, "__init__", reckless)
    monkeypatch.setattr(Executor, "_watch_physics", lambda self: None)
    missed = _run(5000016)
    assert missed.outcome == "missed" and "contact load" in missed.why
    assert missed.peak_load_n > 100.0


def test_a_campaign_summary_counts_outcomes_with_intervals_and_names_each_miss_by_seed() -> None:
    runs = run_group(group_specs(CampaignRequest(runs=4, seed=7), CELL, range(4))[0])
    s = summarize(runs, seed=7, delay_ms=3000, jitter_ms=0, drop_probability=0, program="peg", mode="composite", world={})
    assert s.runs == 4 and s.fault_free_runs == 1 and sum(s.faults.values()) == 4
    assert s.caught + s.missed + s.absorbed + s.false_stops + s.hung == 3 + (runs[0].outcome != "clean")
    assert runs[0].outcome == "clean" and s.false_stop_rate == 0.0 and s.false_stop_interval[1] < 1.0
    assert s.misses == [] and s.missed_rate_upper_95 is not None


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "server.cli", "trial", "faults", *args], capture_output=True, text=True, timeout=600)


def test_the_command_prints_the_summary_and_replays_a_seed(tmp_path) -> None:
    out = _cli("--clock", "virtual", "--runs", "3", "--seed", "7", "--json")
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    for key in ("runs", "faults", "caught", "missed", "false_stops", "stop_latency_ms", "misses"):
        assert key in summary
    assert summary["runs"] == 3 and {"p50", "p99"} <= set(summary["stop_latency_ms"])
    replayed = _cli("--replay", "7000001", "--json", "--out", str(tmp_path))
    assert replayed.returncode == 0, replayed.stderr
    assert json.loads(replayed.stdout)["seed"] == 7000001
    from mcap.reader import make_reader

    with open(tmp_path / "teleprog-fault-7000001.mcap", "rb") as f:
        topics = [channel.topic for _, channel, _ in make_reader(f).iter_messages()]
    assert topics[0] == "/fault/fault" and topics[-1] == "/fault/run" and topics.count("/fault/ground_truth") > 100


@pytest.mark.parametrize(("args", "says"), [
    (["--runs", "0"], "--runs"),
    (["--kind", "meteor"], "--kind meteor"),
    (["--drop-probability", "0.5"], "--drop-probability"),
    (["--program", "/nonexistent.tp"], "--program"),
])
def test_bad_flags_are_one_line_naming_the_flag(args: list[str], says: str) -> None:
    out = _cli(*args)
    assert out.returncode != 0 and says in out.stderr and "Traceback" not in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_local_workers_give_the_same_results_as_this_process() -> None:
    request = CampaignRequest(runs=12, seed=12, kinds=("sensor_dropout", "object_missing"))
    here, _ = run_campaign(request, CELL)
    there, _ = run_campaign(request.model_copy(update={"workers": 2}), CELL)
    assert [r.seed for r in here] == list(range(run_seed(12, 0), run_seed(12, 12)))
    assert [r.model_dump() for r in here] == [r.model_dump() for r in there]
