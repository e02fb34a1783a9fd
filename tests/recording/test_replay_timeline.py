"""The replay's reading of a recording: what the console showed at a moment, the marks to step
between, and a submitted range's plan against the robot's reported motion.

The recording is written by the real writer with a known story, so every figure the replay
derives has an answer worked out here by hand: a range of two statements planned to move the
tool 100 mm along x in 1.0 s; the robot runs it, is 5 mm off in y at plan time 0.5 s, and
finishes the move 0.12 s late."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from support import wait_for

from server.console.enums import SentStatus
from server.console.views import SentListView, SentView
from server.recording import records
from server.recording.reader import read_recording
from server.recording.writer import RecordingWriter
from server.replay.comparison import compare_ranges
from server.replay.player import ReplayPlayer, open_replay
from server.replay.timeline import Timeline
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.errors import InputError
from shared.language.parser import parse_statement
from shared.paths import PROJECT_DIR

T0 = 1_800_000_000_000_000_000  # ns, the console's clock at the start
S = 1_000_000_000
P0 = np.array([0.5, 0.0, 0.5])  # world m, the tool at plan time 0
ROBOT_T0 = 10.0  # s, the robot's clock when it starts the move
SUBMIT = T0 + 1 * S  # console time of the submission
ARRIVE = 0.3  # s: a frame reaches the console this long after the robot's own time
DELAY = 0.25  # s, the link's one-way delay as measured
TEXTS = ["SPEED 20 %", "MOVES TO (600, 0, 500) mm (180, 0, 0) deg"]


def planned(t: float) -> np.ndarray:
    return P0 + np.array([0.1 * min(max(t, 0.0), 1.0), 0.0, 0.0])


def frame_time(k: int) -> int:
    """Console time at which telemetry frame ``k`` (robot time ROBOT_T0 + 0.02 k) is recorded."""
    return SUBMIT + int((0.5 + 0.02 * k + ARRIVE) * S)


def sent(statuses: list[SentStatus]) -> SentListView:
    items = [SentView(id=i + 1, number=i + 1 if s is not SentStatus.SENDING else None, text=TEXTS[i],
                      statement=parse_statement(TEXTS[i]), status=s, submitted_at=SUBMIT * 1e-9)
             for i, s in enumerate(statuses)]
    return SentListView(items=items, pending=sum(s not in (SentStatus.DONE,) for s in statuses))


def status(id_: int, number: int | None, what: str) -> records.StatementStatus:
    return records.StatementStatus(id=id_, number=number, text=TEXTS[id_ - 1], status=what, final=what == "done",
                                   submitted_at=SUBMIT * 1e-9)


@pytest.fixture(scope="module")
def recording_path(tmp_path_factory) -> Path:
    cell = load_cell(DEFAULT_CELL)
    base_T_world = np.linalg.inv(cell.world_T_base)
    path = tmp_path_factory.mktemp("replay") / "story.mcap"
    w = RecordingWriter(path)
    w.start()
    cell_file = str(Path(DEFAULT_CELL).resolve().relative_to(PROJECT_DIR))
    w.put(records.SESSION, T0, records.SessionStart(cell=cell.name, cell_file=cell_file, robot=cell.robot.name,
                                                    dof=cell.robot.dof, started_at=T0 * 1e-9, delay_s=DELAY))
    q0 = [0.0] * cell.robot.dof
    w.put(records.VIRTUAL_ARM, T0, records.VirtualArm(q=q0, world_T_tool=np.eye(4).tolist(), version=1))
    w.put(records.VIRTUAL_ARM, T0 + S // 2, records.VirtualArm(q=[0.1] * cell.robot.dof, world_T_tool=np.eye(4).tolist(),
                                                              version=2))
    w.put(records.event_topic("link"), T0, {"type": "link", "link": {"status": "live", "delay_s": DELAY}})
    w.put(records.event_topic("regime"), T0 + S // 4, {"type": "regime", "regime": {"regime": "free", "zone": "free"}})
    plan_t = [round(0.1 * i, 1) for i in range(11)]
    plan = records.PlannedPath(t=plan_t, q=[q0] * 11, world_p_tool=[planned(t).tolist() for t in plan_t],
                               statement_starts=[0.0, 0.0], statement_ends=[0.0, 1.0], complete=True)
    w.put(records.SUBMITTED, SUBMIT, records.RangeSubmitted(ids=[1, 2], texts=TEXTS, start_q=q0, plan=plan))
    w.put(records.SENT, SUBMIT, sent([SentStatus.SENDING, SentStatus.SENDING]))
    for i in (1, 2):
        w.put(records.STATUS, SUBMIT, status(i, None, "sending"))
    w.put(records.event_topic("predicted"), SUBMIT, {"type": "predicted", "predicted": {"points": [planned(t).tolist() for t in plan_t]}})
    # the robot's frames: statement 2 runs 1.10 s (to k = 55), then idles
    for k in range(0, 66):
        tau = 0.02 * k
        p = planned(tau) + (np.array([0.0, 0.005, 0.0]) if k == 25 else 0.0)
        base_p = (base_T_world @ np.append(p, 1.0))[:3]
        w.put(records.TELEMETRY, frame_time(k), records.Telemetry(
            robot_time=ROBOT_T0 + tau, frame=k, state="running" if k <= 55 else "idle", mode="position",
            statement=2 if k <= 55 else 0, q=q0, base_p_tool=base_p.tolist(), base_rpy_tool=[0, 0, 0], gripper=0.0,
            wrench=[0.0] * 6))
        if k == 0:
            w.put(records.SENT, frame_time(0), sent([SentStatus.DONE, SentStatus.RUNNING]))
            w.put(records.STATUS, frame_time(0), status(1, 1, "done"))
            w.put(records.STATUS, frame_time(0), status(2, 2, "running"))
        if k == 56:
            w.put(records.SENT, frame_time(56), sent([SentStatus.DONE, SentStatus.DONE]))
            w.put(records.STATUS, frame_time(56), status(2, 2, "done"))
            w.put(records.event_topic("predicted"), frame_time(56), {"type": "predicted", "predicted": {"points": []}})
    w.close()
    return path


def test_the_moment_shows_what_the_console_showed_then(recording_path: Path) -> None:
    timeline = Timeline(read_recording(recording_path))
    before = timeline.at(SUBMIT - 1)
    assert before.sent is None and before.remote_q is None and before.predicted == []
    assert before.virtual_q == [0.1] * len(before.virtual_q)  # the second arm message (0.5 s) is the newest
    assert timeline.at(T0).virtual_q == [0.0] * len(before.virtual_q)
    assert before.regime == "free" and before.link_status == "live"

    t = frame_time(25) + S // 20  # 50 ms after frame 25 arrived; frame 26 arrives 20 ms after 25
    m = timeline.at(t)
    assert m.remote_statement == 2 and m.remote_state == "running"
    # frame 27 arrived 10 ms before t: its state is 10 ms + the link's delay old
    assert m.remote_age_s == pytest.approx((t - frame_time(27)) * 1e-9 + DELAY)
    assert [(s.number, s.status) for s in m.sent.items] == [(1, SentStatus.DONE), (2, SentStatus.RUNNING)]
    assert len(m.predicted) == 11
    after = timeline.at(frame_time(60))
    assert [s.status for s in after.sent.items] == [SentStatus.DONE, SentStatus.DONE] and after.predicted == []
    assert timeline.at(T0 - 10 * S).t_s == 0.0 and timeline.at(T0 + 100 * S).t_ns == timeline.end  # clamped


def test_marks_step_through_statuses_regime_and_submission(recording_path: Path) -> None:
    timeline = Timeline(read_recording(recording_path))
    kinds = [(m.kind, m.t_ns) for m in timeline.marks]
    assert ("submitted", SUBMIT) in kinds and ("regime", T0 + S // 4) in kinds
    assert [m.text for m in timeline.marks if m.kind == "status"][-1] == "#2 MOVES TO (600, 0, 500) mm (180, 0, 0) deg: done"
    first = timeline.next_mark(T0)
    assert first.kind == "regime"  # the link's first status is at T0 itself, not after it
    assert timeline.next_mark(first.t_ns).kind in ("submitted", "status") and timeline.next_mark(first.t_ns).t_ns == SUBMIT
    assert timeline.previous_mark(SUBMIT).kind == "regime"
    assert timeline.next_mark(timeline.end) is None


def test_the_plan_and_the_reported_motion_are_compared_in_space_and_time(recording_path: Path) -> None:
    cell = load_cell(DEFAULT_CELL)
    [c] = compare_ranges(read_recording(recording_path), cell.world_T_base)
    assert c.numbers == [1, 2] and c.texts == TEXTS
    assert c.largest_gap_m == pytest.approx(0.005, abs=1e-9)
    assert c.largest_gap_at_s == pytest.approx(0.5)
    np.testing.assert_allclose(c.largest_gap_points[0], planned(0.5), atol=1e-9)
    assert c.largest_path_gap_m == pytest.approx(0.005, abs=1e-9)
    worst = c.largest_time_gap
    assert worst.number == 2 and worst.planned_end_s == 1.0 and worst.late_s == pytest.approx(0.12)
    assert len(c.reported_world_p_tool) == 56  # the frames that name the range's statements
    text = "\n".join(c.lines())
    assert "5.0 mm at 0.50 s" in text and "0.12 s later than planned" in text


def test_the_comparison_says_whether_a_gap_is_timing_or_a_deviation(recording_path: Path) -> None:
    """A successful run's 140 mm "largest gap" with the robot on the planned path is timing (it ran
    behind or ahead of the plan), and the page says so; a gap from the path is called a deviation."""
    import dataclasses

    [c] = compare_ranges(read_recording(recording_path), load_cell(DEFAULT_CELL).world_T_base)
    timing = dataclasses.replace(c, largest_gap_m=0.1406, largest_path_gap_m=0.0012)
    assert any(line.startswith("the robot stayed within 5 mm of the planned path: the gap at the same time is timing")
               for line in timing.lines())
    away = dataclasses.replace(c, largest_gap_m=0.1406, largest_path_gap_m=0.031)
    assert any(line.startswith("the robot left the planned path by up to 31.0 mm") for line in away.lines())
    assert "the robot followed the plan in place and in time" in c.lines()  # the fixture's 5 mm both ways


def test_the_player_seeks_steps_and_plays_to_the_end(recording_path: Path) -> None:
    player = ReplayPlayer(open_replay(recording_path), recording_path.parent)
    seen = []
    player.on_moment(seen.append)
    try:
        player.seek((SUBMIT - T0) * 1e-9 + 0.9)
        assert player.view().sent[1].status == "running"
        mark = player.step(1)
        assert mark.kind == "status" and player.view().t_s == pytest.approx((frame_time(56) - T0) * 1e-9)
        player.step(-1)
        assert player.view().t_s == pytest.approx((frame_time(0) - T0) * 1e-9)
        player.play(speed=2.0)
        assert player.playing
        wait_for(lambda: not player.playing, 10, 0.02, "the playhead at the end")
        assert player.view().t_s == pytest.approx(player.view().duration_s)
        times = [m.t_ns for m in seen[3:]]
        assert times == sorted(times) and len(times) > 5  # the playhead advanced in steps
        with pytest.raises(InputError, match="speed"):
            player.set_speed(0.0)
    finally:
        player.close()


def test_a_file_that_is_not_a_recording_is_refused_in_one_sentence(tmp_path: Path) -> None:
    bad = tmp_path / "notes.mcap"
    bad.write_text("these are not the droids")
    with pytest.raises(InputError, match="not a session recording"):
        open_replay(bad)
    empty = tmp_path / "empty.mcap"
    w = RecordingWriter(empty)
    w.start()
    w.put(records.LOG, T0, {"message": "hello"})
    w.close()
    with pytest.raises(InputError, match="no session start"):
        open_replay(empty)


def test_teleprog_replay_refuses_a_bad_file_in_one_line(tmp_path: Path) -> None:
    import subprocess
    import sys

    bad = tmp_path / "notes.mcap"
    bad.write_text("these are not the droids")
    for path in (bad, tmp_path / "missing.mcap"):
        out = subprocess.run([sys.executable, "-m", "server.cli", "replay", str(path), "--port", "0"],
                             capture_output=True, text=True, timeout=60, cwd=PROJECT_DIR)
        assert out.returncode != 0
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("teleprog: error: ") and str(path) in lines[0], out.stderr
