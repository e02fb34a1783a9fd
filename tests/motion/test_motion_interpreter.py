"""The interpreter's state, parameter and task statements, and whole-program plans."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.errors import InputError, JointLimitError
from shared.language.statements import Draw, Drive, Event, Mode, Move, SetMode, SetSpeed, Speed, TaskCall
from shared.motion import Interpreter, PlanRefused, RefusalReason, SegmentKind, plan_program
from shared.paths import ASSETS_DIR
from shared.robots.loader import load_robot

ROBOT = load_robot("puma562")
Q0 = np.radians([0.0, -45.0, 180.0, 0.0, 45.0, 0.0])
QA = np.radians([20.0, -60.0, 170.0, 10.0, 30.0, 5.0])


def test_parameter_statements_take_no_time_and_set_the_state() -> None:
    interp = Interpreter(ROBOT, Q0)
    for st in (SetSpeed(speed=Speed(value=0.8, unit="fraction")), SetMode(mode=Mode.FORCE), Event(name="ready")):
        seg = interp.plan_next(st)
        assert seg.kind is SegmentKind.PARAMETER and seg.duration == 0.0
        np.testing.assert_array_equal(seg.q_end, Q0)
    assert interp.state.speed.value == 0.8 and interp.state.mode is Mode.FORCE and interp.state.index == 3
    assert seg.event == "ready"
    move = interp.plan_next(Move(joints=tuple(QA)))
    assert move.mode is Mode.FORCE  # the mode in force travels with the motion
    np.testing.assert_array_equal(interp.state.q, QA)
    np.testing.assert_allclose(interp.state.world_T_tcp, ROBOT.fk(QA), atol=1e-12)


def test_a_task_is_handed_to_the_executor_and_nothing_is_planned_after_it() -> None:
    interp = Interpreter(ROBOT, Q0)
    seg = interp.plan_next(TaskCall(name="insert_peg", args=("PEG", "HOLE1")))
    assert seg.kind is SegmentKind.TASK and seg.duration == 0.0 and seg.statement.name == "insert_peg"
    with pytest.raises(PlanRefused) as info:
        interp.plan_next(Move(joints=tuple(QA)))
    assert info.value.reason is RefusalReason.AFTER_TASK
    interp.resume_at(QA)  # the executor ran the task and reports the arm's pose
    seg = interp.plan_next(Drive(joint=1, target=0.0))
    np.testing.assert_array_equal(seg.q_start, QA)


def test_a_bad_start_is_an_input_error() -> None:
    with pytest.raises(InputError, match="6 joints"):
        Interpreter(ROBOT, [0.0, 0.0])
    with pytest.raises(JointLimitError, match="outside its range"):
        Interpreter(ROBOT, np.radians([0.0, 90.0, 0.0, 0.0, 0.0, 0.0]))


def test_plan_program_gives_durations_and_the_final_joint_vector(cell) -> None:
    program = [
        SetSpeed(speed=Speed(value=1.0, unit="fraction")),
        Move(joints=tuple(QA)),
        Draw(position=(0.0, 0.0, 0.15), frame="WORK"),
        Event(name="above"),
        Drive(joint=6, target=math.radians(30.0)),
        TaskCall(name="insert_peg", args=("PEG", "HOLE2")),
    ]
    plan = plan_program(program, cell.robot, cell)
    assert plan.ok and len(plan.segments) == len(program)
    np.testing.assert_array_equal(plan.q_start, cell.q_home)
    d = plan.durations
    assert d[0] == 0.0 and d[1] > 0 and d[2] > 0 and d[3] == 0.0 and d[4] > 0 and d[5] == 0.0
    assert plan.duration == pytest.approx(float(np.sum(d)))
    assert math.isclose(plan.q_final[5], math.radians(30.0))
    np.testing.assert_allclose(plan.start_times, np.concatenate([[0.0], np.cumsum(d)[:-1]]))


def test_plan_sampling_is_continuous_across_statements(cell) -> None:
    program = [Move(joints=tuple(QA)), Draw(position=(0.02, 0.0, 0.15), frame="WORK"), Drive(joint=6, target=0.5)]
    plan = plan_program(program, cell.robot, cell)
    for start, seg in zip(plan.start_times, plan.segments):
        before, after = plan.sample(np.array([start - 1e-9, start + 1e-9])).q
        np.testing.assert_allclose(before, after, atol=1e-6)
        np.testing.assert_allclose(plan.sample(start).q[0], seg.q_start, atol=1e-12)
    end = plan.sample(np.array([plan.duration, plan.duration + 5.0])).q
    np.testing.assert_array_equal(end, [plan.q_final, plan.q_final])
    ts = np.linspace(-1.0, plan.duration + 1.0, 5001)
    dq = np.abs(np.diff(plan.sample(ts).q, axis=0))
    assert np.max(dq) < 0.01  # no jumps anywhere (1.5 rad/s * 1.3 ms is 2 mrad)


def test_a_refused_statement_ends_the_plan_there(cell) -> None:
    program = [Move(joints=tuple(QA)), Draw(position=(3.0, 0.0, 1.0)), Move(joints=tuple(Q0))]
    plan = plan_program(program, cell.robot, cell)
    assert not plan.ok
    assert plan.refusal.reason is RefusalReason.UNREACHABLE and plan.refusal.index == 1
    assert len(plan.segments) == 1
    np.testing.assert_array_equal(plan.q_final, QA)


def test_plan_program_without_a_cell_starts_at_zero_and_checks_the_robot(cell, tmp_path) -> None:
    plan = plan_program([Drive(joint=2, target=-0.5)], ROBOT)
    np.testing.assert_array_equal(plan.q_start, np.zeros(6))
    source = (ASSETS_DIR / "robots" / "puma562" / "robot.toml").read_text()
    other_file = tmp_path / "other.toml"
    other_file.write_text(source.replace('name = "puma562"', 'name = "other_arm"', 1))
    other = load_robot(str(other_file))
    assert other.name == "other_arm"
    with pytest.raises(InputError, match="holds robot"):
        plan_program([], other, cell)


def test_task_contracts_say_where_the_arm_is_after_a_task(cell) -> None:
    interp = Interpreter.for_cell(cell)
    start = interp.state.world_T_tcp.copy()
    grasp = interp.plan_next(TaskCall(name="grasp", args=("peg",)))
    assert grasp.arm_end == "still"
    np.testing.assert_array_equal(grasp.q_end, grasp.q_start)
    extract = interp.plan_next(TaskCall(name="extract_peg", args=("PEG", "HOLE1")))
    assert extract.arm_end == "retract" and extract.duration == 0.0
    axis = cell.features["HOLE1"].world_T_feature[:3, 2]
    np.testing.assert_allclose(interp.state.world_T_tcp[:3, 3], start[:3, 3] + 0.05 * axis, atol=1e-6)
    # the program goes on from the retracted pose
    seg = interp.plan_next(Draw(position=(0.0, 0.0, -0.01), frame="TOOL"))
    np.testing.assert_array_equal(seg.q_start, extract.q_end)
    interp.plan_next(TaskCall(name="insert_peg", args=("peg", "HOLE2")))
    assert interp.state.after_task == "insert_peg"
    # after a task with an unknown end: parameters and still tasks yes, motion no
    interp.plan_next(SetMode(mode=Mode.POSITION))
    interp.plan_next(TaskCall(name="release"))
    for st in (Drive(joint=1, target=0.0), TaskCall(name="extract_peg", args=("peg", "HOLE2"))):
        with pytest.raises(PlanRefused) as info:
            interp.plan_next(st)
        assert info.value.reason is RefusalReason.AFTER_TASK and "insert_peg" in str(info.value)


def test_the_peg_transfer_example_plans(cell) -> None:
    from shared.language.parser import parse_file

    parsed = parse_file(ASSETS_DIR / "programs" / "peg_transfer.tp")
    assert parsed.ok, parsed.error_lines()
    plan = plan_program(parsed.statements, cell.robot, cell)
    assert plan.ok, plan.refusal
    assert len(plan.segments) == len(parsed.statements) and plan.duration > 0


def test_plan_sampling_takes_times_in_any_order(cell) -> None:
    plan = plan_program([Move(joints=tuple(QA)), Event(name="x"), Drive(joint=6, target=0.5)], cell.robot, cell)
    ts = np.linspace(-0.5, plan.duration + 0.5, 301)
    shuffled = np.random.default_rng(0).permutation(ts)
    in_order = plan.sample(ts)
    mixed = plan.sample(shuffled)
    back = np.argsort(shuffled)
    np.testing.assert_array_equal(mixed.q[back], in_order.q)
    np.testing.assert_array_equal(mixed.qd[back], in_order.qd)
    np.testing.assert_array_equal(in_order.q[0], plan.q_start)


def test_plan_sampling_matches_each_segments_own_samples(cell) -> None:
    program = [Move(joints=tuple(QA)), Draw(position=(0.02, 0.0, 0.15), frame="WORK"), Drive(joint=6, target=0.5)]
    plan = plan_program(program, cell.robot, cell)
    for start, seg in zip(plan.start_times, plan.segments):
        local = np.linspace(0.0, seg.duration, 37)[1:-1]
        whole, own = plan.sample(start + local), seg.sample(local)
        np.testing.assert_allclose(whole.q, own.q, atol=1e-12)
        np.testing.assert_allclose(whole.qd, own.qd, atol=1e-12)
        np.testing.assert_allclose(whole.qdd, own.qdd, atol=1e-9)
