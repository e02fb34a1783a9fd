"""``shared.motion.plan_check``: checking a plan before anything moves.

The oracles: the planner's own segments and sampling (the input of ``check_plan``, not its
answer), the collision scene asked directly (``SceneModel.check``) at the times the issues name,
and joint ranges written here."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel
from shared.collision.cell_check import CellCollision
from shared.errors import InputError, TeleprogError
from shared.language.parser import parse_program
from shared.motion import plan_check
from shared.motion.interpreter import Plan, plan_program
from shared.motion.plan_check import PlanCheck, check_plan, plan_or_refuse

DT = 0.05
INTO_THE_TABLE = "DRAW TO (550, 0, -600) mm IN BASE"


@pytest.fixture(scope="module")
def cell():
    return load_cell(DEFAULT_CELL)


@pytest.fixture(scope="module")
def collision(cell) -> CellCollision:
    # a coarser hierarchy than the console's builds in a fraction of the time; the answers are
    # exact either way (leaves are tested triangle against triangle)
    return CellCollision(cell, scene=SceneModel.from_cell(cell, leaf_size=8))


def parse(text: str):
    parsed = parse_program(text, "test.tp")
    assert parsed.ok, parsed.error_lines()
    return parsed.statements


def plan(cell, text: str) -> Plan:
    return plan_program(parse(text), cell.robot, cell, start_q=cell.q_home)


def test_a_clean_program_has_no_issues(cell, collision) -> None:
    p = plan(cell, "DRIVE J1 TO 10 deg\nDRIVE J2 TO -50 deg")
    checked = check_plan(p, cell.robot, collision, 0, 2, dt=DT)
    assert isinstance(checked, PlanCheck)
    assert checked.issues == () and checked.refusal is None
    assert checked.duration == pytest.approx(p.durations.sum()) and checked.duration > 0


def test_a_target_past_the_joint_range_is_the_planners_refusal_on_its_statement(cell, collision) -> None:
    # J2's range is [-205, 45] deg
    p = plan(cell, "DRIVE J1 TO 10 deg\nDRIVE J2 TO 60 deg")
    assert p.refusal is not None
    checked = check_plan(p, cell.robot, collision, 0, 2, dt=DT)
    assert checked.refusal == str(p.refusal)
    refused = [i for i in checked.issues if i.kind == "plan"]
    assert len(refused) == 1 and refused[0].index == 1 and refused[0].t == 0.0
    assert "J2" in refused[0].message and "statement 2" in refused[0].message
    assert not [i for i in checked.issues if i.kind == "joint_limit"]  # the planned part stays in range


def test_a_sample_past_the_joint_range_is_a_joint_limit_issue_on_its_statement(cell, collision) -> None:
    # J2 goes from its home (-45.52 deg) to -30 deg in statement 2; checked against a J2 range
    # narrowed to end at -40 deg, the samples of statement 2 leave it once J2 passes -40 deg
    p = plan(cell, "DRIVE J1 TO 10 deg\nDRIVE J2 TO -30 deg\nDRIVE J1 TO 5 deg")
    assert p.refusal is None
    limit = math.radians(-40.0)
    upper = cell.robot.upper.copy()
    upper[1] = limit
    narrow = SimpleNamespace(lower=cell.robot.lower.copy(), upper=upper)
    checked = check_plan(p, narrow, collision, 0, 3, dt=DT)
    limits = [i for i in checked.issues if i.kind == "joint_limit"]
    # statement 2 leaves the range, and statement 3 starts and stays out of it (J2 at -30 deg)
    assert [i.index for i in limits] == [1, 2]
    first = limits[0]
    assert "statement 2" in first.message and "joint 2" in first.message
    # the first sample of statement 2 past -40 deg: J2 there is beyond, one sample earlier not
    begin, end = p.start_times[1], p.start_times[1] + p.segments[1].duration
    assert begin <= first.t <= end
    assert p.sample(first.t).q[0][1] > limit
    assert p.sample(first.t - DT).q[0][1] <= limit
    assert limits[1].t == pytest.approx(p.start_times[2], abs=DT)
    assert "statement 3" in limits[1].message and "joint 2" in limits[1].message
    # the robot's real ranges: nothing
    assert not [i for i in check_plan(p, cell.robot, collision, 0, 3, dt=DT).issues if i.kind == "joint_limit"]


def test_a_draw_into_the_table_reports_the_links_and_the_table(cell, collision) -> None:
    p = plan(cell, INTO_THE_TABLE)
    assert p.refusal is None  # the planner does not know about the table
    checked = check_plan(p, cell.robot, collision, 0, 1, dt=DT)
    hits = [i for i in checked.issues if i.kind == "collision"]
    assert hits and all(i.index == 0 and "statement 1" in i.message for i in hits)
    table = [i for i in hits if "table" in i.bodies]
    assert table
    for issue in table:
        link = next(b for b in issue.bodies if b != "table")
        assert link.startswith("link")
        assert f"{link} touches table" in issue.message
    # each pair is reported once, at its first touching sample: the scene asked directly
    # agrees that the pair touches there and not one sample earlier
    scene = collision.scene
    pairs = [i.bodies for i in hits]
    assert len(pairs) == len(set(pairs))
    for issue in hits:
        now = {(x.a, x.b) for x in scene.check(p.sample(issue.t).q[0], distances="none").pairs}
        assert issue.bodies in now
        if issue.t >= DT:
            before = {(x.a, x.b) for x in scene.check(p.sample(issue.t - DT).q[0], distances="none").pairs}
            assert issue.bodies not in before


def test_objects_moved_away_are_checked_where_they_are(cell, collision) -> None:
    p = plan(cell, INTO_THE_TABLE)
    far = np.eye(4)
    far[:3, 3] = (-2.0, -2.0, 3.0)  # plate out of the way, high up behind the robot
    checked = check_plan(p, cell.robot, collision, 0, 1, dt=DT, object_poses={"plate": far})
    bodies = {b for i in checked.issues for b in i.bodies or ()}
    assert "table" in bodies and "plate" not in bodies


def test_the_range_starts_and_lasts_as_the_plan_says(cell, collision) -> None:
    p = plan(cell, "DRIVE J1 TO 10 deg\nSPEED 50 %\nDRIVE J2 TO -50 deg\nDRIVE J1 TO 0 deg")
    d = [s.duration for s in p.segments]
    assert d[1] == 0.0  # SPEED takes no time
    whole = check_plan(p, cell.robot, collision, 0, 4, dt=DT)
    assert whole.t0 == 0.0 and whole.duration == pytest.approx(sum(d))
    middle = check_plan(p, cell.robot, collision, 1, 3, dt=DT)
    assert middle.t0 == pytest.approx(d[0]) and middle.t0 == pytest.approx(p.start_times[1])
    # statements 2..3 (SPEED and the DRIVE of J2): the last statement is not part of the range
    assert middle.duration == pytest.approx(d[1] + d[2])
    tail = check_plan(p, cell.robot, collision, 2, 4, dt=DT)
    assert tail.t0 == pytest.approx(d[0] + d[1]) and tail.duration == pytest.approx(d[2] + d[3])


def test_a_range_ignores_what_comes_after_it(cell, collision) -> None:
    """A plan of more statements than the range: the collision of statement 2 is not the range's."""
    p = plan(cell, f"DRIVE J1 TO 10 deg\n{INTO_THE_TABLE}")
    first_only = check_plan(p, cell.robot, collision, 0, 1, dt=DT)
    assert first_only.issues == ()
    assert first_only.duration == pytest.approx(p.segments[0].duration)
    both = check_plan(p, cell.robot, collision, 0, 2, dt=DT)
    assert both.issues and {i.index for i in both.issues} == {1}


def test_statement_at_q_at_and_statement_ends(cell, collision) -> None:
    p = plan(cell, "DRIVE J1 TO 10 deg\nDRIVE J2 TO -50 deg\nDRIVE J3 TO 190 deg")
    d = [s.duration for s in p.segments]
    checked = check_plan(p, cell.robot, collision, 0, 3, dt=DT)
    assert checked.statement_ends() == pytest.approx([d[0], d[0] + d[1], d[0] + d[1] + d[2]])
    assert checked.statement_starts() == pytest.approx([0.0, d[0], d[0] + d[1]])
    assert checked.statement_at(0.5 * d[0]) == 0
    assert checked.statement_at(d[0] + 0.5 * d[1]) == 1
    assert checked.statement_at(d[0] + d[1] + 0.5 * d[2]) == 2
    assert checked.statement_at(-1.0) == 0 and checked.statement_at(100.0) == 2  # clipped into the range
    # q at the ends of the statements: the targets written in the program
    assert checked.q_at(d[0])[0] == pytest.approx(math.radians(10.0), abs=1e-9)
    assert checked.q_at(d[0] + d[1])[1] == pytest.approx(math.radians(-50.0), abs=1e-9)
    np.testing.assert_allclose(checked.q_at(-5.0), cell.q_home, atol=1e-12)
    end = cell.q_home.copy()
    end[:3] = np.radians([10.0, -50.0, 190.0])
    np.testing.assert_allclose(checked.q_at(1e3), end, atol=1e-9)
    # half way through statement 2: J1 done, J2 between its start and its target
    q = checked.q_at(d[0] + 0.5 * d[1])
    assert q[0] == pytest.approx(math.radians(10.0), abs=1e-9)
    assert min(cell.q_home[1], math.radians(-50)) < q[1] < max(cell.q_home[1], math.radians(-50))
    # a range from statement 2: times count from its start
    later = check_plan(p, cell.robot, collision, 1, 3, dt=DT)
    assert later.statement_ends() == pytest.approx([d[1], d[1] + d[2]])
    assert later.statement_at(0.0) == 1 and later.statement_at(d[1] + 0.5 * d[2]) == 2
    assert later.q_at(0.0)[0] == pytest.approx(math.radians(10.0), abs=1e-9)


def test_plan_or_refuse_plans_like_the_planner(cell) -> None:
    statements = parse("DRIVE J1 TO 10 deg\nDRIVE J2 TO -50 deg")
    got = plan_or_refuse(statements, cell.robot, cell, cell.q_home)
    direct = plan_program(statements, cell.robot, cell, start_q=cell.q_home)
    np.testing.assert_allclose(got.q_final, direct.q_final)
    assert got.duration == pytest.approx(direct.duration)


@pytest.mark.parametrize("error", [FloatingPointError("overflow in multiply"), ValueError("cannot convert float NaN to integer"),
                                   IndexError("index 99 is out of bounds"), np.linalg.LinAlgError("singular matrix")])
def test_plan_or_refuse_turns_a_numerical_failure_into_input_error(cell, monkeypatch, error) -> None:
    def broken(*args, **kwargs):
        raise error

    monkeypatch.setattr(plan_check, "plan_program", broken)
    with pytest.raises(InputError) as refused:
        plan_or_refuse(parse("DRIVE J1 TO 10 deg"), cell.robot, cell, cell.q_home)
    assert type(error).__name__ in str(refused.value) and str(error) in str(refused.value)
    assert refused.value.__cause__ is None and refused.value.__suppress_context__


def test_plan_or_refuse_passes_the_projects_errors_and_others_through(cell, monkeypatch) -> None:
    class Refusal(TeleprogError):
        pass

    def refusing(*args, **kwargs):
        raise Refusal("no")

    monkeypatch.setattr(plan_check, "plan_program", refusing)
    with pytest.raises(Refusal):
        plan_or_refuse([], cell.robot, cell, cell.q_home)

    def crashing(*args, **kwargs):
        raise RuntimeError("a bug, not the input")

    monkeypatch.setattr(plan_check, "plan_program", crashing)
    with pytest.raises(RuntimeError):
        plan_or_refuse([], cell.robot, cell, cell.q_home)
