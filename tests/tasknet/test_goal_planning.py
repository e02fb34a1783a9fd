"""Goals of a task space (issue 40): the shortest action run on the task space's net, its
statements from the motion templates and the cell's modelled poses, and the program planning
from home and being recognised as the planned actions."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shared.cells.loader import load_cell
from shared.cells.object_world import ObjectWorld
from shared.errors import InputError
from shared.language.parser import parse_file, parse_program
from shared.motion.frames import CellFrames
from shared.motion.plan_check import plan_or_refuse
from shared.tasknet.action_program import action_statements, cell_marking, program_text
from shared.tasknet.goals import parse_goal, plan_goal
from shared.tasknet.playback import PrefixRecognition, recognise_program
from shared.tasknet.taskspace import load_task_space

ROOT = Path(__file__).resolve().parents[2]
CELL = ROOT / "assets" / "cells" / "peg_in_hole.toml"
TASK = ROOT / "assets" / "tasks" / "peg_in_hole.toml"
TRANSFER = ["grasp(PEG)", "part(PEG,HOLE1)", "mate(PEG,HOLE2)", "release(PEG)"]


@pytest.fixture(scope="module")
def cell():
    return load_cell(CELL)


@pytest.fixture(scope="module")
def space():
    return load_task_space(TASK)


@pytest.fixture(scope="module")
def m0(space, cell):
    return cell_marking(space, cell)


@pytest.fixture(scope="module")
def transfer(space, cell, m0):
    plan = plan_goal(space, m0, ["PEGINHOLE(PEG,HOLE2)"])
    return plan, program_text(action_statements(space, cell, plan.actions))


def test_the_cell_as_loaded_gives_the_thesis_marking(m0) -> None:
    assert m0 == {"HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE1)", "HOLEEMPTY(HOLE2)"}


def test_the_peg_in_hole2_is_the_thesis_transfer(transfer) -> None:
    plan, _ = transfer
    assert plan.action_texts == TRANSFER
    assert plan.kept == ("HANDEEMPTY", "PEGFREE(PEG)")
    assert set(plan.final) == {"HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE2)", "HOLEEMPTY(HOLE1)"}
    assert 1 <= plan.states_visited < 100


def test_without_keeping_the_plan_stops_at_the_goal(space, m0) -> None:
    assert plan_goal(space, m0, "PEGINHOLE(PEG,HOLE2)", keep=False).action_texts == TRANSFER[:3]
    # the hand holding the peg keeps it in its hole
    assert plan_goal(space, m0, "HOLDING(PEG)").action_texts == ["grasp(PEG)"]
    # a goal that holds already needs nothing
    assert plan_goal(space, m0, "PEGINHOLE(PEG,HOLE1)").action_texts == []


def test_goal_names_resolve_as_the_task_space_has_them(space) -> None:
    assert parse_goal(space, "pegInHole(peg, hole2); HOLDING(PEG)") == ("PEGINHOLE(PEG,HOLE2)", "HOLDING(PEG)")
    assert parse_goal(space, ["PEGINHOLE(PEG,HOLE2)", "PEGINHOLE(PEG,HOLE2)"]) == ("PEGINHOLE(PEG,HOLE2)",)


@pytest.mark.parametrize("goal, words", [
    ("PEGINHOLE(PEG,HOLE1); PEGINHOLE(PEG,HOLE2)", ["PEGINHOLE(PEG,HOLE2)", "cannot hold together", "PEGINHOLE(PEG,HOLE1)"]),
    ("HOLDING(PEG), HANDEEMPTY", ["HANDEEMPTY", "cannot hold together", "HOLDING(PEG)"]),
    ("FOO(PEG)", ["no predicate 'FOO'", "PEGINHOLE"]),
    ("HOLDING(HOLE1)", ["HOLDING(HOLE1)", "not an atom"]),
    ("PEGINHOLE(PEG,HOLE9)", ["'HOLE9'", "individuals"]),
    ("", ["empty"]),
])
def test_a_goal_that_cannot_be_reached_says_which_atom(space, m0, goal, words) -> None:
    with pytest.raises(InputError) as err:
        plan_goal(space, m0, goal)
    assert all(w in str(err.value) for w in words), str(err.value)


def test_an_atom_no_action_adds_is_named_with_the_reason(space) -> None:
    # from a marking with the peg held and nothing else, HOLEEMPTY(HOLE1) needs a part from HOLE1
    # which cannot happen: the peg is in no hole
    with pytest.raises(InputError, match=r"HOLEEMPTY\(HOLE1\) holds in no marking reachable .*part\(PEG,HOLE1\)"):
        plan_goal(space, {"HOLDING(PEG)"}, "HOLEEMPTY(HOLE1)")


def test_the_statements_come_from_the_modelled_poses(space, cell, transfer) -> None:
    plan, text = transfer
    # the thesis's own statements (assets/programs/peg_transfer.tp), in its order
    thesis = [s for s in (ln.split("#")[0].strip() for ln in (ROOT / "assets/programs/peg_transfer.tp").read_text().splitlines())
              if s and not s.startswith("EVENT")]
    ours = [ln for ln in text.splitlines() if not ln.startswith("#")]
    assert ours == thesis
    # each action's statements follow a comment naming it
    assert [ln[len("# action "):] for ln in text.splitlines() if ln.startswith("# action ")] == TRANSFER
    assert all(r.statements for r in space.spec.rules)  # every rule's template is in the task file


def test_the_statements_follow_the_cell_not_constants(space, tmp_path) -> None:
    moved = tmp_path / "peg_in_hole.toml"
    moved.write_text(CELL.read_text().replace("[0.0, 80.0, 40.0]", "[0.0, 100.0, 40.0]"))
    rows = action_statements(space, load_cell(moved), [space.action(a) for a in TRANSFER])
    assert "DRAW TO (0, 100, 125) mm IN WORK WITH SPEED 10 mm/s" in rows[2].statements


def test_the_program_plans_from_home_and_is_recognised_as_the_plan(space, cell, transfer) -> None:
    plan, text = transfer
    parsed = parse_program(text)
    assert parsed.ok, parsed.error_lines()
    planned = plan_or_refuse(parsed.statements, cell.robot, cell, cell.q_home)
    assert planned.refusal is None
    assert len(planned.segments) == len(parsed.statements)
    recognised = recognise_program(parsed.statements, cell, space)
    assert recognised.refusal is None
    assert [a.action for a in recognised.actions] == plan.action_texts
    assert set(recognised.final_marking) == set(plan.final)


def test_net_plan_cli_json_and_an_unreachable_goal() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "server.cli", "net", "plan", "--cell", "assets/cells/peg_in_hole.toml",
         "--goal", "PEGINHOLE(PEG,HOLE2)", "--json"], capture_output=True, text=True, timeout=180, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["actions"] == TRANSFER
    assert "TASK insert_peg(peg, HOLE2)" in data["program"]
    assert isinstance(data["states_visited"], int) and data["states_visited"] > 0
    bad = subprocess.run(
        [sys.executable, "-m", "server.cli", "net", "plan", "--cell", "assets/cells/peg_in_hole.toml",
         "--goal", "PEGINHOLE(PEG,HOLE1);PEGINHOLE(PEG,HOLE2)"], capture_output=True, text=True, timeout=180, cwd=ROOT)
    assert bad.returncode != 0
    assert "Traceback" not in bad.stderr and bad.stderr.count("\n") == 1
    assert "PEGINHOLE(PEG,HOLE2)" in bad.stderr and bad.stdout == ""


def test_the_enabled_actions_follow_the_marking_and_never_put_an_object_in_two_places(cell, space) -> None:
    from shared.tasknet.goals import enabled_actions, resolve_action

    start = cell_marking(space, cell)
    assert [a.text for a in enabled_actions(space, start)] == ["grasp(PEG)"]
    holding = (start - {"HANDEEMPTY", "PEGFREE(PEG)"}) | {"HOLDING(PEG)"}
    offered = [a.text for a in enabled_actions(space, holding)]
    # the rules let mate(PEG,HOLE2) fire with the peg still in HOLE1; the offer leaves it out
    assert "part(PEG,HOLE1)" in offered and "mate(PEG,HOLE2)" not in offered and "grasp(PEG)" not in offered
    assert resolve_action(space, "PART(peg, hole1)").text == "part(PEG,HOLE1)"
    with pytest.raises(InputError, match="no action 'fly\\(PEG\\)'"):
        resolve_action(space, "fly(PEG)")


def test_an_actions_statements_start_from_where_the_objects_are_now(cell, space) -> None:
    """A grasp of a peg the operator moved goes to the peg, not to where the cell loads it."""
    from shared.tasknet.goals import resolve_action

    peg = next(o for o in cell.objects if o.name == "peg")
    moved = np.array(peg.world_T_object, dtype=float)
    moved[:3, 3] += [0.05, 0.02, 0.0]
    grasp = [resolve_action(space, "grasp(PEG)")]
    (as_loaded,) = action_statements(space, cell, grasp)
    (now,) = action_statements(space, cell, grasp, poses={"peg": moved})
    assert as_loaded.statements != now.statements
    work_T_world = np.linalg.inv(cell.frame("work"))
    x, y = ((work_T_world @ moved)[:2, 3] * 1e3).round(2)
    assert f"({x:g}, {y:g}," in now.statements[1].replace(".0,", ",")  # MOVES TO above the moved peg


def test_a_rule_template_that_names_an_unknown_field_or_variable_is_refused_at_load(tmp_path) -> None:
    from shared.errors import FileFormatError

    text = (ROOT / "assets" / "tasks" / "peg_in_hole.toml").read_text()
    for bad, says in (('"TASK grasp({obj p})"', "{obj q}"), ('"TASK grasp({obj p})"', "{lift p}")):
        path = tmp_path / "bad.toml"
        path.write_text(text.replace(bad, f'"TASK grasp({says})"', 1))
        with pytest.raises(FileFormatError, match="rule grasp") as caught:
            load_task_space(path)
        assert str(path) in str(caught.value) and ("q" in str(caught.value) or "lift" in str(caught.value))


SWAP = ["grasp(PEGA)", "part(PEGA,HOLE1)", "mate(PEGA,HOLE3)", "release(PEGA,HOLE3)",
        "grasp(PEGB)", "part(PEGB,HOLE2)", "mate(PEGB,HOLE1)", "release(PEGB,HOLE1)"]


@pytest.mark.parametrize("goal, keep, actions", [
    ("PEGINHOLE(PEGA,HOLE3)", True, ["grasp(PEGA)", "part(PEGA,HOLE1)", "mate(PEGA,HOLE3)", "release(PEGA,HOLE3)"]),
    # HOLE1 holds PEGA: the plan first takes PEGA to the only free hole (the hand lets go only in a
    # hole here), then brings PEGB
    ("PEGINHOLE(PEGB,HOLE1), HANDEEMPTY", False, SWAP),
    # keeping what the goal does not change (HOLE3 empty): PEGA ends in the hole PEGB left
    ("PEGINHOLE(PEGB,HOLE1), HANDEEMPTY", True,
     [*SWAP, "grasp(PEGA)", "part(PEGA,HOLE3)", "mate(PEGA,HOLE2)", "release(PEGA,HOLE2)"]),
])
def test_the_second_task_space_plans_goals_that_play_as_their_actions(goal, keep, actions) -> None:
    """The two-peg cell (issue 40: a second task space, nothing of it in code): the plan, its
    program from the templates in its task file, and the program played on the virtual cell
    recognised as the planned actions."""
    cell = load_cell(ROOT / "assets" / "cells" / "two_pegs.toml")
    space = load_task_space(ROOT / "assets" / "tasks" / "two_pegs.toml")
    start = cell_marking(space, cell)
    assert start == {"HANDEEMPTY", "PEGFREE(PEGA)", "PEGFREE(PEGB)", "PEGINHOLE(PEGA,HOLE1)", "PEGINHOLE(PEGB,HOLE2)",
                     "HOLEEMPTY(HOLE3)"}
    plan = plan_goal(space, start, goal, keep=keep)
    assert plan.action_texts == actions
    # one transfer per program: what follows an insertion waits for the robot's report of it; each
    # transfer is played from where the one before left the cell (its objects and the arm)
    world, q, marking = ObjectWorld(cell), cell.q_home.copy(), None
    for first in range(0, len(actions), 4):
        chunk = plan.actions[first:first + 4]
        poses = world.poses(CellFrames.from_cell(cell).world_T_tcp(cell.robot, q))
        program = parse_program(program_text(action_statements(space, cell, chunk, poses=poses))).statements
        kept = PrefixRecognition(cell, space, q, world)
        recognised = kept.recognise(program)
        assert [a.action for a in recognised.actions] == [a.text for a in chunk]
        world, q, marking = kept.world_at_end(), kept.q_end, recognised.final_marking
    assert set(parse_goal(space, goal)) <= set(marking)
