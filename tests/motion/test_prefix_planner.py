"""Planning successive versions of a program from the first changed statement gives what
``plan_program`` gives from the start, whatever changed: appended, replaced, inserted, taken
out, a refused statement fixed or broken, a task leaving the pose unknown."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.errors import JointLimitError
from shared.language.parser import parse_file
from shared.language.statements import Draw, Drive, Event, Move, SetSpeed, Speed, TaskCall
from shared.motion import plan_program
from shared.motion.prefix_planner import PrefixPlanner, common_prefix
from shared.paths import ASSETS_DIR

QA = (math.radians(20.0), math.radians(-60.0), math.radians(170.0), math.radians(10.0), math.radians(30.0), math.radians(5.0))

POOL = [
    SetSpeed(speed=Speed(value=0.5, unit="fraction")),
    SetSpeed(speed=Speed(value=1.0, unit="fraction")),
    Move(joints=QA),
    Draw(position=(0.0, 0.0, 0.02), frame="WORK"),
    Draw(position=(0.01, 0.0, 0.0), frame="TOOL"),
    Draw(position=(3.0, 0.0, 1.0)),  # out of reach: refused
    Drive(joint=6, target=math.radians(30.0)),
    Drive(joint=1, target=math.radians(-10.0)),
    Event(name="here"),
    TaskCall(name="grasp", args=("peg",)),
    TaskCall(name="insert_peg", args=("PEG", "HOLE2")),  # the pose after it is unknown
]


def assert_same_plan(ours, theirs) -> None:
    assert len(ours.segments) == len(theirs.segments)
    for a, b in zip(ours.segments, theirs.segments):
        assert a.index == b.index and a.statement == b.statement and a.kind is b.kind
        assert a.duration == b.duration
        np.testing.assert_array_equal(a.q_start, b.q_start)
        np.testing.assert_array_equal(a.q_end, b.q_end)
    assert (ours.refusal is None) == (theirs.refusal is None)
    if ours.refusal is not None:
        assert ours.refusal.index == theirs.refusal.index and ours.refusal.reason is theirs.refusal.reason
        assert str(ours.refusal) == str(theirs.refusal)
    np.testing.assert_array_equal(ours.q_start, theirs.q_start)
    np.testing.assert_array_equal(ours.q_final, theirs.q_final)
    np.testing.assert_array_equal(ours.start_times, theirs.start_times)
    assert ours.after_task == theirs.after_task


def test_random_edits_plan_as_from_the_start(cell) -> None:
    rng = np.random.default_rng(7)
    planner = PrefixPlanner(cell.robot, cell, cell.q_home)
    program: list = []
    kinds = {"append": 0, "replace_last": 0, "insert": 0, "remove": 0, "refused": 0}
    for step in range(300):
        r = rng.random()
        pick = POOL[int(rng.integers(len(POOL)))]
        if r < 0.45 or not program:
            program.append(pick)
            kinds["append"] += 1
        elif r < 0.7:
            program[-1] = pick
            kinds["replace_last"] += 1
        elif r < 0.85:
            program.insert(int(rng.integers(len(program) + 1)), pick)
            kinds["insert"] += 1
        else:
            del program[int(rng.integers(len(program)))]
            kinds["remove"] += 1
        if len(program) > 25:
            del program[: len(program) - 25]
        theirs = plan_program(program, cell.robot, cell, start_q=cell.q_home)
        kinds["refused"] += theirs.refusal is not None
        assert_same_plan(planner.plan(program), theirs)
        assert planner.durations() == [float(seg.duration) for seg in theirs.segments]
    assert all(v > 10 for v in kinds.values()), kinds  # every kind of change was tried


def test_the_common_prefix_is_found_by_slices_as_a_walk_finds_it() -> None:
    rng = np.random.default_rng(3)
    for _ in range(500):
        a = list(rng.integers(0, 3, int(rng.integers(0, 12))))
        b = list(rng.integers(0, 3, int(rng.integers(0, 12))))
        if rng.random() < 0.5:
            b = a[: int(rng.integers(0, len(a) + 1))] + b
        walked = next((i for i, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
        assert common_prefix(a, b) == common_prefix(tuple(a), tuple(b)) == walked


def test_a_growing_program_plans_only_its_new_statements(cell, monkeypatch) -> None:
    parsed = parse_file(ASSETS_DIR / "programs" / "peg_transfer.tp")
    statements = list(parsed.statements)
    planner = PrefixPlanner(cell.robot, cell, cell.q_home)
    planned: list = []
    original = planner._interp.plan_next
    monkeypatch.setattr(planner._interp, "plan_next", lambda st: (planned.append(st), original(st))[1])
    for n in range(1, len(statements) + 1):
        assert_same_plan(planner.plan(statements[:n]), plan_program(statements[:n], cell.robot, cell, start_q=cell.q_home))
    assert planned == statements  # each statement planned once
    planned.clear()
    planner.plan(statements[:-1] + [Event(name="instead")])
    assert planned == [Event(name="instead")]


def test_a_start_outside_the_joint_ranges_is_refused_as_plan_program_refuses_it(cell) -> None:
    with pytest.raises(JointLimitError) as theirs:
        plan_program([], cell.robot, cell, start_q=np.full(6, 10.0))
    with pytest.raises(JointLimitError) as ours:
        PrefixPlanner(cell.robot, cell, np.full(6, 10.0))
    assert str(ours.value) == str(theirs.value)


def test_the_plan_of_a_prefix_is_plan_program_of_that_prefix(cell) -> None:
    """``plan_first(statements, stop)`` (a preview's range planned by the program's planner) is
    ``plan_program(statements[:stop])`` for every stop, before, at and after a refusal."""
    program = [POOL[0], POOL[2], POOL[3], POOL[6], POOL[5], POOL[7], POOL[8]]  # POOL[5] is refused
    planner = PrefixPlanner(cell.robot, cell, cell.q_home)
    for stop in range(len(program) + 1):
        ours = planner.plan_first(program, stop)
        assert_same_plan(ours, plan_program(program[:stop], cell.robot, cell, start_q=cell.q_home))
        assert (ours.refusal is not None) == (stop > 4)
    # and the whole program stays kept: planning it again re-plans nothing
    before = planner._segments[:]
    planner.plan(program)
    assert all(a is b for a, b in zip(before, planner._segments))
