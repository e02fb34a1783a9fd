"""The console session in-process: generation from the arm's motion, editor rules, preview
player and its warnings, regimes, the control lock, program files, typed events."""

from __future__ import annotations

import math

import numpy as np
import pytest

from server.console import (
    ArmChanged,
    Caller,
    CollisionChanged,
    ConflictError,
    DisplayMode,
    NotConnectedError,
    PreviewChanged,
    ProgramChanged,
    RefusedByRule,
    Regime,
    Session,
)
from shared.errors import InputError, JointLimitError
from shared.language.statements import Frame


def _stroke(session: Session, clock, dx: float, steps: int = 8) -> None:
    for _ in range(steps):
        session.arm.jog_tool(frame="world", constraint="x", motion="translate", displacement=np.array([dx / steps, 0.0, 0.0]))
        clock.advance(0.02)


def test_generation_follows_the_arm_and_flushes_on_release(session: Session, clock, cell_and_scene) -> None:
    cell, _ = cell_and_scene
    events = []
    session.subscribe_events(events.append)
    session.program.set_auto_generate(True)
    x0 = session.arm.view().tool_xyz_mm[0]
    _stroke(session, clock, 0.04)
    program = session.arm.release()
    kinds = [e.kind for e in program.entries]
    assert kinds == ["DRAW", "EMPTY"]
    draw = program.entries[0].statement
    assert session.arm.view().tool_xyz_mm[0] == pytest.approx(x0 + 40.0, abs=0.5)  # the arm went 40 mm along world x
    # the target is where the arm went: the tool point after the jog, computed here from the
    # arm's joints by forward kinematics (world_T_base @ fk(q) @ flange_T_tcp), then expressed
    # in the statement's frame; DRAW positions are metres (shared/language/statements.py)
    world_tcp = cell.world_T_base @ cell.robot.fk(session.arm.state.q) @ cell.flange_T_tcp
    np.testing.assert_allclose(world_tcp[:3, 3] * 1e3, session.arm.view().tool_xyz_mm, atol=1e-6)
    out_T_world = {
        Frame.WORLD: np.eye(4), Frame.BASE: np.linalg.inv(cell.world_T_base), Frame.WORK: np.linalg.inv(cell.frame("work")),
    }[draw.frame]
    expected = (out_T_world @ world_tcp)[:3, 3]
    # within 0.05 mm: the stroke ends on the arm's last sample, written to the 0.1 mm the operator controls
    np.testing.assert_allclose(np.array(draw.position), expected, atol=0.5e-4)  # the text's 0.1 mm
    for _ in range(6):
        session.arm.jog_joint(1, np.radians(2.0))
        clock.advance(0.02)
    program = session.arm.release()
    assert [e.kind for e in program.entries] == ["DRAW", "DRIVE", "EMPTY"]
    assert program.entries[1].statement.joint == 1
    assert program.entries[1].statement.target == pytest.approx(session.arm.state.q[0], abs=math.radians(0.05) + 1e-12)  # the text holds 0.1 deg
    assert any(isinstance(e, ArmChanged) for e in events)
    assert any(isinstance(e, CollisionChanged) for e in events)
    assert any(isinstance(e, ProgramChanged) for e in events)


def test_auto_generation_off_adds_nothing(session: Session, clock) -> None:
    session.program.set_auto_generate(False)  # on by default (issue 16)
    _stroke(session, clock, 0.03)
    assert session.arm.release().empty_index == 0


def test_editor_refusals_name_their_rule_and_undo_restores(session: Session) -> None:
    session.program.set_strict_editing(True)  # the thesis's rules; free editing: tests/program/test_free_editing*.py
    session.program.insert("DRIVE J1 TO 10 deg")
    session.program.insert("DRIVE J2 TO -40 deg")
    session.program.select(0)
    with pytest.raises(RefusedByRule) as refused:
        session.program.delete()
    assert refused.value.refusal.rule.value == "delete.action-not-last"
    with pytest.raises(RefusedByRule) as refused:
        session.program.insert("DRIVE J3 TO 5 deg")
    assert refused.value.refusal.rule.value == "insert.action-at-end"
    session.program.insert("SPEED 20 %")  # parameters go anywhere
    assert [e.kind for e in session.program.view().entries] == ["SPEED", "DRIVE", "DRIVE", "EMPTY"]
    view = session.program.undo()
    assert [e.kind for e in view.entries] == ["DRIVE", "DRIVE", "EMPTY"]
    assert view.can_redo
    with pytest.raises(InputError, match="column"):
        session.program.insert("DRIVE J1 TO")


def test_preview_plays_without_changing_program_or_arm_and_locks_edits(session: Session, clock) -> None:
    session.program.insert("DRIVE J1 TO 10 deg")
    session.program.insert("DRIVE J2 TO -50 deg")
    q_before = session.arm.state.q.copy()
    program_before = session.program.view().entries
    view = session.preview.begin(0, 2)
    assert view.active and view.duration > 0 and view.current == 0 and not view.warnings
    assert session.modes.display is DisplayMode.TASK_PREVIEW
    with pytest.raises(RefusedByRule, match="preview"):
        session.program.insert("SPEED 10 %")
    with pytest.raises(ConflictError, match="previewed"):
        session.arm.jog_joint(1, 0.1)
    session.program.select(0)  # selection is allowed
    first = session.preview.step(1)
    assert 0 < first.t < view.duration and first.current in (0, 1)
    assert first.q[0] == pytest.approx(np.radians(10.0), abs=1e-6)
    last = session.preview.step(1)
    assert last.t == pytest.approx(view.duration)
    assert last.q[1] == pytest.approx(np.radians(-50.0), abs=1e-6)
    assert session.program.view().confirmed == (0, 2)
    session.preview.seek(0.0)
    events = []
    session.subscribe_events(events.append)
    session.preview.play(20.0)
    clock.advance(view.duration / 20.0 / 2)
    session.tick()  # the app's loop ticks at the player rate; here the test moves the clock
    halfway = session.preview.view()
    assert halfway.playing and halfway.t == pytest.approx(view.duration / 2)
    assert any(isinstance(e, PreviewChanged) and e.preview.playing for e in events)
    clock.advance(view.duration / 20.0)
    session.tick()
    assert not session.preview.view().playing
    assert session.preview.view().t == pytest.approx(view.duration)
    last = [e for e in events if isinstance(e, PreviewChanged)][-1]  # the tick published the end
    assert not last.preview.playing and last.preview.t == pytest.approx(view.duration)
    session.preview.end()
    assert session.modes.display is DisplayMode.TELEPROGRAMMING
    np.testing.assert_array_equal(session.arm.state.q, q_before)
    assert session.program.view().entries == program_before
    # an edit after the preview withdraws the confirmation
    session.program.insert("EVENT checked")
    assert session.program.view().confirmed is None


def test_preview_warns_about_collisions_with_the_table(session: Session) -> None:
    session.program.insert("DRAW TO (550, 0, -600) mm IN BASE")
    view = session.preview.begin(0, 1)
    hits = [w for w in view.warnings if w.kind == "collision"]
    assert hits and any("table" in w.bodies or "plate" in w.bodies for w in hits)
    assert "statement 1" in hits[0].message
    session.preview.step(1)
    assert session.program.view().confirmed is None  # warnings: not a confirmation
    session.preview.seek(view.duration)
    assert session.preview.view().colliding_now


def test_driving_into_the_table_reports_collision_and_zone(session: Session) -> None:
    assert session.arm.collision_view().zone in (Regime.FREE, Regime.QUASI)
    for _ in range(80):
        session.arm.jog_tool(frame="world", constraint="z", motion="translate", displacement=np.array([0, 0, -0.01]))
        if session.arm.collision_view().colliding:
            break
    view = session.arm.collision_view()
    assert view.colliding and view.pairs and view.triangles
    assert view.zone is Regime.OPERATION
    assert session.modes.regime is Regime.OPERATION
    session.modes.set_regime_override(Regime.FREE)
    assert session.modes.regime_view().regime is Regime.FREE and session.modes.regime_view().zone is Regime.OPERATION


def test_control_lock_lets_others_only_observe(session: Session) -> None:
    grant = session.control.request("alice")
    alice = Caller("alice", grant.token)
    with pytest.raises(ConflictError, match="alice"):
        session.control.request("bob")
    with pytest.raises(ConflictError, match="observe"):
        session.arm.jog_joint(1, 0.05, client="bob")
    with pytest.raises(ConflictError):
        session.arm.jog_joint(1, 0.05)  # the page too
    with pytest.raises(ConflictError, match="token"):
        session.arm.jog_joint(1, 0.05, client="alice")  # the name alone proves nothing
    session.arm.jog_joint(1, 0.05, client=alice)
    assert session.snapshot().control.holder == "alice"
    assert grant.token not in session.snapshot().model_dump_json()
    with pytest.raises(ConflictError):
        session.control.release("bob")
    with pytest.raises(ConflictError):
        session.control.release("alice")
    session.control.release(alice)
    session.arm.jog_joint(1, 0.05, client="bob")


def test_program_files_load_save_and_broken_files_keep_the_program(session: Session) -> None:
    session.program.load("SPEED 50 %\nDRIVE J1 TO 15 deg\nTASK grasp(PEG)\n", "ok.tp")
    text = session.program.save("text")
    assert "DRIVE J1 TO 15 deg" in text and "TASK grasp(PEG)" in text
    as_json = session.program.save("json")
    session.program.load(as_json, "copy.json")
    assert [e.kind for e in session.program.view().entries] == ["SPEED", "DRIVE", "TASK", "EMPTY"]
    with pytest.raises(InputError, match=r"broken\.tp:2:"):
        session.program.load("SPEED 10 %\nDRAW TO (1, 2) mm\n", "broken.tp")
    with pytest.raises(InputError, match="task"):
        session.program.load("TASK insert_peg(PEG, HOLE2)\nDRIVE J1 TO 1 deg\n", "after_task.tp")
    assert [e.kind for e in session.program.view().entries] == ["SPEED", "DRIVE", "TASK", "EMPTY"]


def test_submit_without_robot_and_joint_limits_are_clear(session: Session) -> None:
    session.program.insert("DRIVE J1 TO 10 deg")
    with pytest.raises(NotConnectedError, match="no robot"):
        session.dispatch.submit(0, 1)
    assert session.program.view().empty_index == 1  # nothing left the program
    with pytest.raises(JointLimitError, match="joint 2"):
        session.arm.set_q(np.radians([0, 90, 0, 0, 0, 0]))


def _frame(q, state, n=1):
    from shared.wire.messages import ControlMode as WireMode
    from shared.wire.telemetry import TelemetryFrame

    return TelemetryFrame(time=0.02 * n, frame=n, state=state, mode=WireMode.POSITION, statement=0,
                          q=tuple(float(v) for v in q), position=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0), gripper=0.03)


def test_divergence_after_a_stop_and_resync_from_telemetry(session: Session) -> None:
    from shared.wire.messages import RobotState

    home = session.arm.state.q.copy()
    session.remote.on_telemetry(_frame(home, RobotState.IDLE, 1))
    view = session.remote.divergence_view()
    assert view.checked and not view.diverged
    remote = session.remote.view()
    assert remote is not None and remote.state == "idle"
    np.testing.assert_allclose(remote.world_T_tcp, session.arm.state.world_T_tcp, atol=1e-9)
    off = home.copy()
    off[0] += np.radians(3.0)
    session.remote.on_telemetry(_frame(off, RobotState.RUNNING, 2))  # moving: not compared
    assert not session.remote.divergence_view().checked
    session.remote.on_telemetry(_frame(off, RobotState.STOPPED, 3))
    view = session.remote.divergence_view()
    assert view.diverged and view.joint_error == pytest.approx(np.radians(3.0), abs=1e-9) and "re-sync" in view.message
    snap = session.resync()
    np.testing.assert_allclose(snap.arm.q, off, atol=1e-12)
    assert snap.program.start_source == "telemetry" and snap.program.start_q == pytest.approx(off.tolist())
    assert not snap.divergence.diverged
    # the program now plans from the re-synced state
    session.program.insert("DRIVE J2 TO -50 deg")
    preview = session.preview.begin(0, 1)
    assert preview.q[0] == pytest.approx(off[0])
