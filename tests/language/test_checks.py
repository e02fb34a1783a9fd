"""Checks against a robot and cell: each rule fires on a program that breaks it, and only then."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shared.cells.loader import load_cell
from shared.errors import InputError, JointLimitError
from shared.language.checks import RULES, check_program
from shared.language.parser import parse_json, parse_program
from shared.language.statements import Draw, Drive, Frame, Move, Moves, Rotate, UntilForce, program_from_json, program_to_json
from shared.language.tasks import EXTRACT_LIFT_M, TASKS, find_task, resolve_name
from shared.robots.loader import load_robot
from shared.spatial import invert

ROOT = Path(__file__).resolve().parents[2]
PEG_CELL = ROOT / "assets" / "cells" / "peg_in_hole.toml"
# gripper pointing down 70 mm above the peg (reachable from the cell's home)
ABOVE_PEG = "MOVES TO (0, -80, 160) mm (180, 0, 0) deg IN WORK\n"


@pytest.fixture(scope="module")
def cell():
    return load_cell(PEG_CELL)


def run(text: str, cell=None, robot=None, q_start=None):
    parsed = parse_program(text, "t.tp")
    assert parsed.ok, parsed.error_lines()
    robot = robot or cell.robot
    return check_program(parsed.statements, robot, cell, q_start=q_start, lines=parsed.lines, cols=parsed.cols)


def rules(result) -> list[tuple[int | None, str]]:
    return [(p.line, p.rule) for p in result.problems]


def test_example_peg_transfer_is_clean(cell) -> None:
    parsed = parse_program((ROOT / "assets" / "programs" / "peg_transfer.tp").read_text())
    result = check_program(parsed.statements, cell.robot, cell, lines=parsed.lines)
    assert result.ok, [p.format("peg_transfer.tp") for p in result.problems]
    # the arm ends above HOLE2 holding nothing; the pose after insert_peg is unknown
    assert result.q_after[0] is not None and result.q_after[-1] is None


def test_joint_count(cell) -> None:
    result = run("MOVE (1, 2, 3, 4, 5) deg\nDRIVE J7 TO 0 deg\nDRIVE J6 TO 10 deg", cell)
    assert rules(result) == [(1, "joints"), (2, "joints")]
    assert "has 6 joints" in result.problems[0].message
    assert "J1 to J6" in result.problems[1].message


def test_joint_limits(cell) -> None:
    result = run("MOVE (0, 0, 0, 0, 120, 0) deg\nDRIVE J3 TO -50 deg\nDRIVE J3 TO -40 deg", cell)
    assert rules(result) == [(1, "limits"), (2, "limits")]
    assert "joint 5 at 120.000 deg" in result.problems[0].message
    assert "[-45.000, 225.000]" in result.problems[1].message
    # a rejected target leaves the arm where it was; the valid DRIVE then moves joint 3 only
    q = result.q_after[2]
    assert np.allclose(np.delete(q, 2), np.delete(cell.q_home, 2)) and np.isclose(np.degrees(q[2]), -40)


def test_reachability(cell) -> None:
    result = run(ABOVE_PEG + "DRAW TO (5000, 0, 0) mm IN WORK\nDRAW TO (0, 80, 160) mm IN WORK", cell)
    assert rules(result) == [(2, "reach")]
    assert "outside the workspace" in result.problems[0].message
    # the good targets are reached: forward kinematics puts the gripper where the statement says
    q = result.q_after[2]
    work_T_tcp = invert(cell.frame("work")) @ cell.world_T_base @ cell.robot.fk(q) @ cell.flange_T_tcp
    assert np.allclose(work_T_tcp[:3, 3], [0.0, 0.08, 0.16], atol=1e-9)
    assert np.allclose(work_T_tcp[:3, 2], [0.0, 0.0, -1.0], atol=1e-9)


def test_unreachable_only_because_of_limits(cell) -> None:
    # a gripper pointing straight up over the table needs a wrist beyond its ranges
    result = run("MOVES TO (0, 0, 160) mm (0, 0, 0) deg IN WORK", cell)
    assert rules(result) == [(1, "reach")]
    assert "only outside the joint ranges" in result.problems[0].message


def test_tool_frame_tracks_the_running_pose(cell) -> None:
    result = run(ABOVE_PEG + "DRAW TO (0, 0, 30) mm IN TOOL\nDRAW TO (0, 0, 30) mm IN TOOL", cell)
    assert result.ok
    poses = [cell.world_T_base @ cell.robot.fk(q) @ cell.flange_T_tcp for q in result.q_after]
    # tool z points down: each TOOL step lowers the gripper 30 mm from where that step starts
    assert np.allclose(poses[1][:3, 3] - poses[0][:3, 3], [0, 0, -0.03], atol=1e-9)
    assert np.allclose(poses[2][:3, 3] - poses[0][:3, 3], [0, 0, -0.06], atol=1e-9)


def test_start_vector_matters(cell) -> None:
    text = "DRAW TO (0, 0, 20) mm IN TOOL"
    a = run(text, cell)
    start = np.radians([10, -45, 180, 0, 40, 150])
    b = run(text, cell, q_start=start)
    assert a.ok and b.ok
    assert not np.allclose(a.q_after[0], b.q_after[0])
    with pytest.raises(InputError, match="6 joints"):
        run(text, cell, q_start=[0, 0])
    with pytest.raises(JointLimitError):
        run(text, cell, q_start=np.radians([0, 0, 0, 0, 150, 0]))


def test_frames_need_a_cell_for_work() -> None:
    robot = load_robot("puma562")
    result = run("DRAW TO (500, 0, 0) mm IN WORK\nDRAW TO (0, 0, 10) mm IN TOOL", robot=robot, q_start=np.radians([0, -45, 180, 0, 45, 0]))
    assert rules(result) == [(1, "frame")]
    assert "needs a cell" in result.problems[0].message


def test_speed_units_per_action(cell) -> None:
    text = (
        "MOVE (0, -45, 190, 0, 30, 160) deg WITH SPEED 10 mm/s\n"  # 1: joint move in mm/s
        "DRIVE J1 TO 5 deg WITH SPEED 10 deg/s\n"  # 2: fine
        + ABOVE_PEG.rstrip("\n") + " WITH SPEED 20 mm/s\n"  # 3: fine (MOVES takes any)
        + "DRAW TO (0, -80, 150) mm IN WORK WITH SPEED 5 deg/s\n"  # 4: DRAW in deg/s
        "ROTATE TO (180, 0, 10) deg IN WORK WITH SPEED 5 mm/s\n"  # 5: ROTATE in mm/s
        "SPEED 20 mm/s\n"  # 6
        "DRIVE J1 TO 0 deg\n"  # 7: a SPEED in mm/s in effect caps the tool point; not an error
        "SPEED 150 %\n"  # 8: above 100 %
        "DRAW TO (0, -80, 160) mm IN WORK WITH SPEED 120 %\n"  # 9: above 100 %
    )
    result = run(text, cell)
    assert rules(result) == [(1, "units"), (4, "units"), (5, "units"), (8, "units"), (9, "units")]
    assert "MOVE cannot take WITH SPEED 10 mm/s: it takes % or deg/s" in result.problems[0].message
    assert "DRAW cannot take WITH SPEED 5 deg/s" in result.problems[1].message
    assert "SPEED 150 % is above 100 %" in result.problems[3].message


def test_task_names_and_arguments(cell) -> None:
    text = (
        ABOVE_PEG + "TASK fly(peg)\n"  # 2 unknown task
    )
    result = run(text, cell)
    assert rules(result) == [(2, "names")]
    assert "known tasks: grasp(OBJECT)" in result.problems[0].message
    text = (
        ABOVE_PEG
        + "TASK grasp(peg, HOLE1)\n"  # 2 wrong count
        + "TASK release()\n"  # 3 fine
        + "TASK grasp(widget)\n"  # 4 unknown object
        + "TASK release()\n"  # 5 (holds nothing after a failed grasp)
        + "TASK grasp(PEG)\n"  # 6 fine, case-insensitive
        + "TASK extract_peg(table, HOLE9)\n"  # 7 fixed object, unknown feature
    )
    result = run(text, cell)
    assert rules(result) == [(2, "names"), (4, "names"), (5, "names"), (7, "names"), (7, "names"), (7, "names")]
    assert "takes 1 argument" in result.problems[0].message
    assert "no object 'widget'" in result.problems[1].message
    assert "holds nothing" in result.problems[2].message
    assert "'table' is fixed" in result.problems[3].message
    assert "no feature 'HOLE9'" in result.problems[4].message
    assert "holds 'peg', not 'table'" in result.problems[5].message


def test_task_names_need_a_cell() -> None:
    robot = load_robot("puma562")
    result = run("TASK grasp(peg)", robot=robot, q_start=np.zeros(6))
    assert rules(result) == [(1, "names")] and "--cell" in result.problems[0].message


def test_extract_lifts_along_the_hole_axis(cell) -> None:
    result = run(ABOVE_PEG + "DRAW TO (0, -80, 70) mm IN WORK\nTASK grasp(peg)\nTASK extract_peg(peg, HOLE1)", cell)
    assert result.ok
    before, after = (cell.world_T_base @ cell.robot.fk(result.q_after[i]) @ cell.flange_T_tcp for i in (2, 3))
    assert np.allclose(after[:3, 3] - before[:3, 3], [0, 0, EXTRACT_LIFT_M], atol=1e-9)


def test_nothing_that_moves_the_arm_may_follow_an_unpredictable_task(cell) -> None:
    base = ABOVE_PEG + "DRAW TO (0, -80, 70) mm IN WORK\nTASK grasp(peg)\nTASK insert_peg(peg, HOLE2)\n"
    ok = run(base + "MODE POSITION\nEVENT done\nTASK release()\nSPEED 10 %", cell)
    assert ok.ok, [p.message for p in ok.problems]
    bad = run(base + "DRAW TO (0, 0, 10) mm IN TOOL\nTASK extract_peg(peg, HOLE2)\nMOVE (0, 0, 0, 0, 0, 0) deg", cell)
    assert rules(bad) == [(5, "program"), (6, "program"), (7, "program")]
    assert "cannot follow TASK insert_peg (line 4)" in bad.problems[0].message
    unknown = run("TASK fly()\nDRIVE J1 TO 0 deg", cell)
    assert rules(unknown) == [(1, "names"), (2, "program")]


def test_json_programs_are_located_by_json_pointer(cell) -> None:
    import json

    statements = parse_program("EVENT a\nMOVE (1, 2) deg\nDRIVE J2 TO 90 deg").statements
    document = program_to_json(statements)
    document.insert(0, {"kind": "EVENT", "name": "bad name"})  # refused by the parser: the pointers skip it
    parsed = parse_json(json.dumps(document))
    result = check_program(parsed.statements, cell.robot, cell, lines=parsed.lines, pointers=parsed.pointers)
    assert [p.format("p.json") for p in result.problems] == [
        "p.json: /2/joints: MOVE gives 2 joint values; robot 'puma562' has 6 joints",
        "p.json: /3/target: DRIVE J2: joint 2 at 90.000 deg is outside its range [-205.000, 45.000] deg",
    ]


def test_problem_format_has_file_line_and_column(cell) -> None:
    result = run("EVENT a\n\n   DRIVE J9 TO 0 deg", cell)
    assert [p.format("x.tp") for p in result.problems] == ["x.tp:3:4: DRIVE J9: robot 'puma562' has joints J1 to J6"]
    assert result.problems[0].index == 1


def test_task_registry() -> None:
    assert set(TASKS) == {"grasp", "release", "extract_peg", "insert_peg"}
    assert find_task("Insert_Peg").signature() == "insert_peg(PEG_OBJECT, HOLE_FEATURE)"
    with pytest.raises(InputError, match="unknown task 'fly'"):
        find_task("fly")
    assert resolve_name("PEG", ("peg", "table")) == "peg"
    assert resolve_name("a", ("A", "a")) == "a"
    assert resolve_name("b", ("A", "B")) == "B"
    assert resolve_name("ab", ("AB", "Ab")) is None  # ambiguous ignoring case
    assert resolve_name("x", ("X1",)) is None


def test_strict_tasks_lets_nothing_follow_any_task(cell) -> None:
    text = ABOVE_PEG + "DRAW TO (0, -80, 70) mm IN WORK\nTASK grasp(peg)\nEVENT held\nTASK release()"
    assert run(text, cell).ok
    parsed = parse_program(text)
    strict = check_program(parsed.statements, cell.robot, cell, lines=parsed.lines, strict_tasks=True)
    assert rules(strict) == [(4, "program"), (5, "program")]
    assert "nothing may follow a task call" in strict.problems[0].message


def test_checks_never_crash_on_random_programs(cell) -> None:
    from hypothesis import given, settings
    from hypothesis import strategies as st

    from test_roundtrip_fuzz import statement  # the statement strategy of the round-trip tests

    wild = st.one_of(statement, st.sampled_from([
        # values within the physical bounds that no robot here can use
        parse_json('[{"kind": "DRAW", "position": [100, -100, 0]}]').statements[0],
        parse_json('[{"kind": "MOVE", "joints": [0, 0, 0, 0, 0, 12.5]}]').statements[0],
        parse_json('[{"kind": "ROTATE", "rpy": [12.5, 0, 0], "frame": "TOOL"}]').statements[0],
        parse_json('[{"kind": "DRIVE", "joint": 32, "target": 1}]').statements[0],
        # values beyond them, in statements built around the models
        Draw.model_construct(position=(1e308, -1e308, 0.0), frame=Frame.WORLD, speed=None, until=None),
        Drive.model_construct(joint=1000000, target=1.0, speed=None, until=None),
    ]))

    @settings(max_examples=60, deadline=None)
    @given(st.lists(wild, max_size=8))
    def run_random(statements) -> None:
        result = check_program(statements, cell.robot, cell)
        assert len(result.q_after) == len(statements)
        for p in result.problems:
            assert 0 <= p.index < len(statements) and p.rule in RULES

    run_random()


def test_non_finite_values_are_problems_not_crashes(cell) -> None:
    from pydantic import ValidationError

    nan, inf = float("nan"), float("inf")
    document = [
        {"kind": "DRAW", "position": [nan, 0, 0]},
        {"kind": "MOVES", "position": [inf, 0, 0], "rpy": [0, 0, 0]},
        {"kind": "MOVE", "joints": [0, 0, 0, 0, 0, -inf]},
        {"kind": "DRIVE", "joint": 1, "target": nan},
        {"kind": "ROTATE", "rpy": [0, 0, 0], "until": {"kind": "force", "newtons": inf}},
    ]
    with pytest.raises(ValidationError) as refused:  # the models refuse every one
        program_from_json(document)
    assert len(refused.value.errors()) == 5
    # statements built around the models are problems of the checks, never crashes
    statements = [
        Draw.model_construct(position=(nan, 0.0, 0.0), frame=Frame.WORLD, speed=None, until=None),
        Moves.model_construct(position=(inf, 0.0, 0.0), rpy=(0.0, 0.0, 0.0), frame=Frame.WORLD, speed=None, until=None),
        Move.model_construct(joints=(0.0, 0.0, 0.0, 0.0, 0.0, -inf), speed=None, until=None),
        Drive.model_construct(joint=1, target=nan, speed=None, until=None),
        Rotate.model_construct(rpy=(0.0, 0.0, 0.0), frame=Frame.WORLD, speed=None, until=UntilForce.model_construct(kind="force", newtons=inf)),
    ]
    result = check_program(statements, cell.robot, cell)
    assert [(p.index, p.rule) for p in result.problems] == [(i, "values") for i in range(5)]
    assert result.problems[2].message == "MOVE: joints is not a finite number"
    assert result.problems[4].json_pointer == "/4/until/newtons"


def test_any_urdf_robot_without_a_cell() -> None:
    robot = load_robot(ROOT / "assets" / "robots" / "ur5" / "ur5_robot.urdf")
    parsed = parse_program(
        "MOVE (0, -90, 90, -90, -90, 0) deg\nDRAW TO (0, 0, 50) mm IN TOOL\nDRAW TO (5000, 0, 0) mm IN BASE", "u.tp"
    )
    result = check_program(parsed.statements, robot, None, lines=parsed.lines)
    assert rules(result) == [(3, "reach")]
    before, after = (robot.fk(result.q_after[i]) for i in (0, 1))
    # 50 mm along the tool's own z axis, from where the DRAW started
    assert np.allclose(after[:3, 3] - before[:3, 3], 0.05 * before[:3, 2], atol=1e-6)


def test_position_only_arm_takes_draw_but_not_orientation() -> None:
    rover = load_cell(ROOT / "assets" / "cells" / "rover_empty.toml")
    text = (
        "MOVE (-27, -30, -210) deg\nDRAW TO (0, 0, 10) mm IN TOOL\n"
        "ROTATE TO (0, 0, 0) deg\nMOVES TO (0, 0, 0) mm (0, 0, 0) deg IN TOOL\nDRAW TO (0, 0, 5000) mm IN BASE"
    )
    result = run(text, rover)
    assert rules(result) == [(3, "reach"), (4, "reach"), (5, "reach")]
    assert "positions its tool point only" in result.problems[0].message
    before, after = (rover.world_T_base @ rover.robot.fk(result.q_after[i]) @ rover.flange_T_tcp for i in (0, 1))
    assert np.allclose(after[:3, 3] - before[:3, 3], 0.01 * before[:3, 2], atol=1e-6)
