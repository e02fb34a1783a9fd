"""What the recorder thins to stay cheap, and what it never loses: every pose of the virtual arm
is in ``/virtual/arm``; ``/events/arm`` only when more than the pose changed; ``/events/collision``
at once when the report changes and its distances at most 10 Hz; ``/tf`` at most 30 Hz per arm;
the last of each thinned stream always. The transforms' two ways to an edge agree."""

from __future__ import annotations

import numpy as np
import pytest

from server.console import Session
from server.console.events import CollisionChanged
from server.console.views import CollisionView
from server.recording import foxglove as fg
from server.recording import records
from server.recording.reader import read_recording
from server.recording.recorder import SessionRecorder
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.paths import ASSETS_DIR

START = 1_764_000_000.0


@pytest.fixture(scope="module")
def cell():
    return load_cell(DEFAULT_CELL)


def _session(cell, clock: list[float]) -> Session:
    session = Session(cell, clock=lambda: 1e6 + clock[0], wall_clock=lambda: START + clock[0])
    session.program.set_auto_generate(False)
    return session


def test_a_drag_keeps_every_pose_and_thins_what_repeats_it(cell, tmp_path) -> None:
    clock = [0.0]
    session = _session(cell, clock)
    recorder = SessionRecorder(session, tmp_path / "drag.mcap", cell_file=DEFAULT_CELL)
    recorder.start()
    seen: list[tuple[int, tuple]] = []  # every collision report the console published

    def report(event) -> None:
        if isinstance(event, CollisionChanged):
            c = event.collision
            seen.append((recorder._now(), (c.colliding, c.pairs, c.nearest, c.zone, c.zone_object)))

    session.bus.events.add(report)
    jogs = 100  # one second at the gizmo's 100 Hz
    for i in range(jogs):
        clock[0] = (i + 1) * 0.01
        session.arm.jog_tool(frame="world", constraint="x", motion="translate", displacement=np.array([1e-3, 0.0, 0.0]))
    stats = recorder.close()
    assert stats.dropped == 0 and stats.cpu_s > 0.0
    changes = [(t, key) for i, (t, key) in enumerate(seen) if i == 0 or key != seen[i - 1][1]]
    assert len(changes) >= 2, "the drag passes from one nearest object to another"
    rec = read_recording(tmp_path / "drag.mcap")

    virtual = rec.on(records.VIRTUAL_ARM)
    assert [m.data["version"] for m in virtual] == list(range(virtual[0].data["version"], virtual[0].data["version"] + jogs + 1))
    np.testing.assert_allclose(virtual[-1].data["q"], session.arm.state.q, atol=1e-12)

    arm_events = rec.on(records.event_topic("arm"))
    assert len(arm_events) == 1  # only the pose changed after the first: /virtual/arm has it

    collision = rec.on(records.event_topic("collision"))
    assert len(collision) <= 16  # of 100: distances at most 10 Hz, plus each change and the one before it
    recorded_at = {m.log_time_ns for m in collision}
    for t, _ in changes:
        assert t in recorded_at  # every change of the report, at its time
    last = collision[-1].data["collision"]
    assert last["min_distance"] == pytest.approx(session.arm.collision_view().min_distance)

    tf = [m for m in rec.on(records.TF) if m.data["transforms"][0]["child_frame_id"] == "virtual/base"]
    assert 25 <= len(tf) <= 32  # 30 Hz
    final = fg.frame_transforms(cell.robot, session.arm.state.q, cell.world_T_base, "virtual", tf[-1].log_time_ns,
                                tool_T_tcp=session.frames.tool_T_tcp)
    def numbers(message: dict) -> list[float]:
        return [t[part][k] for t in message["transforms"] for part, keys in (("translation", "xyz"), ("rotation", "xyzw"))
                for k in keys]

    assert numbers(tf[-1].data) == pytest.approx(numbers(final), abs=1e-12)  # the last pose always


def _collision(colliding: bool, distance: float) -> CollisionChanged:
    return CollisionChanged(collision=CollisionView(
        colliding=colliding, pairs=[("link6", "table")] if colliding else [], min_distance=distance, zone="free"))


def test_a_change_of_the_collision_report_goes_out_at_once_after_the_distances_held_back(cell, tmp_path) -> None:
    clock = [0.0]
    session = _session(cell, clock)
    recorder = SessionRecorder(session, tmp_path / "hit.mcap", cell_file=DEFAULT_CELL)
    recorder.start()
    recorder.on_event(_collision(False, 0.050))
    for i, d in enumerate((0.040, 0.030, 0.020), start=1):  # within a tenth of a second: held back
        clock[0] = i * 0.01
        recorder.on_event(_collision(False, d))
    clock[0] = 0.04
    recorder.on_event(_collision(True, 0.0))  # contact: at once, the held 20 mm before it
    recorder.close()
    got = [(m.data["collision"]["colliding"], m.data["collision"]["min_distance"])
           for m in read_recording(tmp_path / "hit.mcap").on(records.event_topic("collision"))]
    assert got == [(False, 0.050), (False, 0.020), (True, 0.0)]


@pytest.mark.parametrize("cell_name", ["peg_in_hole.toml", "rover_empty.toml"])
def test_both_ways_to_an_edge_give_the_same_transforms(cell_name: str, monkeypatch) -> None:
    cell = load_cell(ASSETS_DIR / "cells" / cell_name)
    robot = cell.robot
    rng = np.random.default_rng(5)
    qs = [rng.uniform(robot.lower, robot.upper) for _ in range(5)]
    assert any(fg._joint_edges(robot)), "the shipped robots' links sit on their joints"
    by_joints = [fg.frame_transforms(robot, q, cell.world_T_base, "virtual", 1, tool_T_tcp=cell.flange_T_tcp) for q in qs]
    monkeypatch.setitem(fg._joint_edges_cache, id(robot), (robot, (0,) * robot.dof))
    by_poses = [fg.frame_transforms(robot, q, cell.world_T_base, "virtual", 1, tool_T_tcp=cell.flange_T_tcp) for q in qs]
    for a, b in zip(by_joints, by_poses):
        for ta, tb in zip(a["transforms"], b["transforms"]):
            assert ta["child_frame_id"] == tb["child_frame_id"]
            assert [ta["translation"][k] for k in "xyz"] == pytest.approx([tb["translation"][k] for k in "xyz"], abs=1e-12)
            assert [ta["rotation"][k] for k in "xyzw"] == pytest.approx([tb["rotation"][k] for k in "xyzw"], abs=1e-12)
