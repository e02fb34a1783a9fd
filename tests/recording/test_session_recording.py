"""A real session (``teleprog up``: telerobot, a 200 ms link, console) leaves one MCAP file that
says exactly what happened: the statements sent, every numbered status, the 3D messages
Foxglove reads; and a console killed mid-session leaves a file that reads up to the kill."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from foxglove_validate import validate
from support import PROJECT_DIR, record_three_statements, start_console, stop_process, wait_for

from server.recording import records
from server.recording.reader import read_recording

pytestmark = pytest.mark.slow


def _one_recording(folder: Path) -> Path:
    found = sorted(folder.glob("*.mcap"))
    assert len(found) == 1, found
    return found[0]


def test_a_headless_session_leaves_one_recording_that_matches_it(tmp_path) -> None:
    folder = tmp_path / "recordings"
    console = start_console(tmp_path, "--delay-ms", "200", "--record", str(folder))
    try:
        sent = record_three_statements(console)
        listed = console.call("GET", "/api/sessions")
        assert listed["recording"]["path"] == str(_one_recording(folder).resolve())
        assert [s["name"] for s in listed["sessions"]] == [_one_recording(folder).name]
        # at least one telemetry frame after the last status, so the remote arm's end is recorded
        wait_for(lambda: console.call("GET", "/api/link")["telemetry_received_ago_s"] < 0.5, 10, 0.05, "telemetry")
    finally:
        stop_process(console.proc)
    assert console.proc.returncode == 0
    path = _one_recording(folder)

    out = subprocess.run([sys.executable, "-m", "server.cli", "record", "summary", str(path), "--json"],
                         capture_output=True, text=True, timeout=120, cwd=PROJECT_DIR)
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["complete"] is True and summary["problem"] is None
    expected = [{"number": s["number"], "text": s["text"], "final": s["status"]} for s in sent["items"]]
    assert [{k: s[k] for k in ("number", "text", "final")} for s in summary["statements"]] == expected
    assert all(s["final"] == "done" for s in summary["statements"])
    for s in summary["statements"]:  # each went through the link's statuses in order
        assert s["statuses"][0] == "sending" and s["statuses"][-1] == "done"
    assert summary["cell"] == "peg_in_hole"
    assert summary["channels"][records.TELEMETRY] > 10  # 50 Hz over seconds
    for topic in (records.SESSION, records.VIRTUAL_ARM, records.TF, records.SCENE, records.PREDICTED_PATH,
                  records.LOG, records.PROGRAM, records.SUBMITTED, records.STATUS, records.SENT, "/events/link",
                  "/events/regime"):
        assert summary["channels"].get(topic, 0) >= 1, topic

    recording = read_recording(path)
    # the numbered statuses as recorded are the console's, one record per status reached
    statuses = [records.StatementStatus.model_validate(m.data) for m in recording.on(records.STATUS)]
    for item in sent["items"]:
        mine = [s for s in statuses if s.id == item["id"]]
        assert mine[-1].number == item["number"] and mine[-1].status == "done" and mine[-1].final
        assert len({s.status for s in mine}) == len(mine)  # no status twice
    submitted = records.RangeSubmitted.model_validate(recording.on(records.SUBMITTED)[0].data)
    assert submitted.texts == [s["text"] for s in sent["items"]] and submitted.plan is not None
    assert submitted.plan.t[-1] == pytest.approx(submitted.plan.statement_ends[-1])
    # the robot's clock is kept in each frame; the console's clock orders the messages
    frames = [records.Telemetry.model_validate(m.data) for m in recording.on(records.TELEMETRY)]
    # (two frames may carry one robot time: the robot may send twice between two steps of its clock)
    assert all(b.frame > a.frame and b.robot_time >= a.robot_time for a, b in zip(frames, frames[1:]))
    assert frames[-1].robot_time > frames[0].robot_time
    times = [m.log_time_ns for m in recording.messages]
    assert times == sorted(times)
    # every 3D message is what Foxglove's published schemas describe
    schema_of = {records.TF: "foxglove.FrameTransforms", records.SCENE: "foxglove.SceneUpdate",
                 records.PREDICTED_PATH: "foxglove.PosesInFrame", records.LOG: "foxglove.Log"}
    for topic, schema in schema_of.items():
        for m in recording.on(topic):
            assert m.schema == schema
            validate(schema, m.data)
    frames_named = {t["child_frame_id"] for m in recording.on(records.TF) for t in m.data["transforms"]}
    assert any(f.startswith(records.VIRTUAL_PREFIX + "/") for f in frames_named)
    assert any(f.startswith(records.REMOTE_PREFIX + "/") for f in frames_named)


def test_a_console_killed_mid_session_leaves_a_file_that_reads_up_to_the_kill(tmp_path) -> None:
    folder = tmp_path / "recordings"
    console = start_console(tmp_path, "--delay-ms", "50", "--record", str(folder))
    try:
        wait_for(lambda: console.call("GET", "/api/link")["status"] == "live", 60, 0.1, "a live link")
        for _ in range(5):
            console.call("POST", "/api/jog/joint", {"joint": 1, "delta_deg": 1.0})
        wait_for(lambda: console.call("GET", "/api/sessions")["recording"]["written"] > 200, 30, 0.1, "telemetry recorded")
        path = _one_recording(folder)
        wait_for(lambda: path.stat().st_size > 2000, 10, 0.1, "a chunk on disk")  # the writer closes one a second
        killed_at = console.call("GET", "/api/arm")
        os.kill(console.proc.pid, signal.SIGKILL)
        console.proc.wait(10)
    finally:
        stop_process(console.proc)
    recording = read_recording(path)
    assert not recording.complete
    assert recording.problem is not None and "cut off" in recording.problem and path.name in recording.problem
    assert recording.on(records.SESSION) and recording.on(records.TELEMETRY)
    jogged = [records.VirtualArm.model_validate(m.data) for m in recording.on(records.VIRTUAL_ARM)]
    assert jogged[-1].q == pytest.approx(killed_at["q"])  # the last jog, more than a second before the kill
    out = subprocess.run([sys.executable, "-m", "server.cli", "record", "summary", str(path)],
                         capture_output=True, text=True, timeout=120, cwd=PROJECT_DIR)
    assert out.returncode == 0, out.stderr
    assert "cut off" in out.stderr and "Traceback" not in out.stderr
    assert "(cut off)" in out.stdout


def test_a_file_that_is_not_a_recording_is_one_clear_line(tmp_path) -> None:
    bogus = tmp_path / "notes.mcap"
    bogus.write_text("these are not the bytes of an MCAP file\n")
    out = subprocess.run([sys.executable, "-m", "server.cli", "record", "summary", str(bogus), "--json"],
                         capture_output=True, text=True, timeout=60, cwd=PROJECT_DIR)
    assert out.returncode == 1
    assert out.stderr.startswith(f"teleprog: error: {bogus}: not a session recording")
    assert len(out.stderr.strip().splitlines()) == 1
    missing = subprocess.run([sys.executable, "-m", "server.cli", "record", "summary", str(tmp_path / "none.mcap")],
                             capture_output=True, text=True, timeout=60, cwd=PROJECT_DIR)
    assert missing.returncode == 1 and "cannot read the recording" in missing.stderr


def test_no_record_writes_nothing(tmp_path) -> None:
    folder = tmp_path / "recordings"
    env_folder = Path(os.environ["TELEPROG_RECORD_DIR"])
    before = set(env_folder.glob("*.mcap"))
    console = start_console(tmp_path, "--no-robot", "--no-record")
    try:
        listed = console.call("GET", "/api/sessions")
        assert listed["recording"] is None
    finally:
        stop_process(console.proc)
    assert not folder.exists() and set(env_folder.glob("*.mcap")) == before
