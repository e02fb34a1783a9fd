"""Task coordination on the peg-in-hole cell (thesis §3.5): the task space grounded from
``assets/tasks/peg_in_hole.toml``, the initial marking recognised from the cell as loaded, the
actions recognised from the faces' contacts while a program plays on the virtual cell, and the
generated task net of Table 3.2."""

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
from shared.tasknet.contacts import CellState, ContactModel
from shared.tasknet.coordinator import TaskCoordinator
from shared.tasknet.playback import recognise_program
from shared.tasknet.taskspace import load_task_space

ROOT = Path(__file__).resolve().parents[2]
CELL = ROOT / "assets" / "cells" / "peg_in_hole.toml"
TASK = ROOT / "assets" / "tasks" / "peg_in_hole.toml"
TRANSFER = ["grasp(PEG)", "part(PEG,HOLE1)", "mate(PEG,HOLE2)", "release(PEG)"]
TABLE_3_2 = ["HANDEEMPTY", "PEGFREE(PEG)", "HOLDING(PEG)", "PEGINHOLE(PEG,HOLE1)", "HOLEEMPTY(HOLE1)",
             "HOLEEMPTY(HOLE2)", "PEGINHOLE(PEG,HOLE2)"]


@pytest.fixture(scope="module")
def cell():
    return load_cell(CELL)


@pytest.fixture(scope="module")
def space():
    return load_task_space(TASK)


def test_the_rules_ground_into_the_task_space_net(space) -> None:
    assert len(space.atoms) == 7  # HANDEEMPTY, PEGFREE, HOLDING, 2 PEGINHOLE, 2 HOLEEMPTY
    assert {a.text for a in space.actions} == {"grasp(PEG)", "release(PEG)", "part(PEG,HOLE1)", "part(PEG,HOLE2)",
                                               "mate(PEG,HOLE1)", "mate(PEG,HOLE2)"}
    part = space.action("part(PEG,HOLE1)")
    assert part.pre == ("HOLDING(PEG)", "PEGINHOLE(PEG,HOLE1)") and part.post == ("HOLDING(PEG)", "HOLEEMPTY(HOLE1)")
    # the corrected release frees the peg, so it can be grasped again
    assert set(space.action("release(PEG)").post) == {"HANDEEMPTY", "PEGFREE(PEG)"}


def test_the_initial_marking_is_recognised_from_where_the_peg_stands(cell, space, tmp_path) -> None:
    frames = CellFrames.from_cell(cell)
    home = frames.world_T_tcp(cell.robot, cell.q_home)
    m0 = TaskCoordinator(space, ContactModel(space, cell), CellState.of_world(ObjectWorld(cell), home)).m0
    assert m0 == {"HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE1)", "HOLEEMPTY(HOLE2)"}
    # the same cell with the peg standing in HOLE2: the marking follows the cell, not the rules
    moved = tmp_path / "peg_in_hole2.toml"
    moved.write_text(CELL.read_text().replace("xyz = [0.0, -80.0, 50.0]", "xyz = [0.0, 80.0, 50.0]"))
    cell2 = load_cell(moved)
    m0_2 = TaskCoordinator(space, ContactModel(space, cell2), CellState.of_world(ObjectWorld(cell2), home)).m0
    assert m0_2 == {"HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE2)", "HOLEEMPTY(HOLE1)"}
    # and standing on the plate between the holes it is in neither
    free = tmp_path / "peg_on_plate.toml"
    free.write_text(CELL.read_text().replace("xyz = [0.0, -80.0, 50.0]", "xyz = [0.0, 0.0, 80.5]"))
    cell3 = load_cell(free)
    m0_3 = TaskCoordinator(space, ContactModel(space, cell3), CellState.of_world(ObjectWorld(cell3), home)).m0
    assert m0_3 == {"HANDEEMPTY", "PEGFREE(PEG)", "HOLEEMPTY(HOLE1)", "HOLEEMPTY(HOLE2)"}


@pytest.mark.parametrize("program", ["peg_transfer.tp", "peg_transfer_plain.tp"])
def test_a_transfer_is_recognised_the_same_with_sub_tasks_or_plain_motions(cell, space, program) -> None:
    result = recognise_program(parse_file(ROOT / "assets" / "programs" / program).statements, cell, space)
    assert result.refusal is None
    assert [a.action for a in result.actions] == TRANSFER
    model = result.net.model
    assert [p.predicate for p in model.places] == TABLE_3_2
    assert [(t.id, t.action) for t in model.transitions] == [
        ("T1", "grasp(PEG)"), ("T2", "release(PEG)"), ("T3", "part(PEG,HOLE1)"), ("T4", "mate(PEG,HOLE2)")]
    assert model.initial_marking == ["P1", "P2", "P4", "P6"]
    # firing the recognised actions in order from the initial marking ends where the task left the cell
    net = result.net.net
    m = net.m0.copy()
    for action in result.actions:
        t = result.net.transition_of(action.action)
        assert t in net.enabled_ids(m), f"{action.action} is not enabled at {net.marking_dict(m)}"
        m = net.fire(m, t)
    ended = {p.predicate for p in model.places if m[net.place_index[p.id]]}
    assert ended == set(result.final_marking) & set(TABLE_3_2)
    assert ended == {"HANDEEMPTY", "PEGFREE(PEG)", "HOLEEMPTY(HOLE1)", "PEGINHOLE(PEG,HOLE2)"}


def test_a_grasp_away_from_the_peg_is_not_recognised(cell, space) -> None:
    """The gripper closes 40 mm beside the peg: the object world holds the peg (it trusts the
    task call), but no finger touches the peg, so no action is recognised, and the marking stays
    while the peg rides away: the state is one the net cannot reach, left to the operator."""
    text = ("SPEED 50 %\nMOVES TO (40, -80, 160) mm (180, 0, 0) deg IN WORK\nDRAW TO (40, -80, 75) mm IN WORK\n"
            "TASK grasp(peg)\nDRAW TO (40, -80, 160) mm IN WORK\n")
    result = recognise_program(parse_program(text).statements, cell, space)
    assert result.refusal is None and result.actions == ()
    assert set(result.final_marking) == {"HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE1)", "HOLEEMPTY(HOLE2)"}


def test_only_the_atoms_the_enabled_actions_change_are_checked(cell, space) -> None:
    contacts = ContactModel(space, cell)
    home = CellFrames.from_cell(cell).world_T_tcp(cell.robot, cell.q_home)
    state = CellState.of_world(ObjectWorld(cell), home)
    coordinator = TaskCoordinator(space, contacts, state)
    full = contacts.pairs_checked
    contacts.pairs_checked = 0
    assert coordinator.observe(state) == []
    # at M0 only grasp is enabled: HOLDING(PEG) and its two deleted atoms are measured
    assert 0 < contacts.pairs_checked < full
    assert {a.text for a in coordinator.enabled()} == {"grasp(PEG)"}


class _SetContacts:
    """A contact model whose answers a test sets: ``truth`` is what every atom reads as now."""

    def __init__(self, truth: dict[str, bool]) -> None:
        self.truth = dict(truth)

    def evaluate(self, state, atoms=None) -> dict[str, bool]:
        return {a: self.truth[a] for a in (self.truth if atoms is None else atoms)}


def test_an_action_is_recognised_only_once_the_atoms_its_rule_deletes_no_longer_hold(space) -> None:
    """grasp(PEG) adds HOLDING(PEG) and deletes HANDEEMPTY and PEGFREE(PEG): fingers that read
    as holding the peg while the hand still reads empty (or the peg still free) are not a grasp
    yet; the marking stays until every deleted atom is false too."""
    m0 = {"HANDEEMPTY": True, "PEGFREE(PEG)": True, "HOLDING(PEG)": False, "PEGINHOLE(PEG,HOLE1)": True,
          "PEGINHOLE(PEG,HOLE2)": False, "HOLEEMPTY(HOLE1)": False, "HOLEEMPTY(HOLE2)": True}
    contacts = _SetContacts(m0)
    state = CellState(np.eye(4), True)  # what the fake contacts read is set on them, not here
    coordinator = TaskCoordinator(space, contacts, state)
    start = coordinator.marking
    assert start == {"HANDEEMPTY", "PEGFREE(PEG)", "PEGINHOLE(PEG,HOLE1)", "HOLEEMPTY(HOLE2)"}
    contacts.truth["HOLDING(PEG)"] = True  # added atom holds, both deleted atoms still hold
    assert coordinator.observe(state) == [] and coordinator.marking == start
    contacts.truth["HANDEEMPTY"] = False  # one deleted atom gone, PEGFREE(PEG) still holds
    assert coordinator.observe(state) == [] and coordinator.marking == start
    contacts.truth["PEGFREE(PEG)"] = False  # now every effect of grasp holds
    assert [a.action for a in coordinator.observe(state, t=2.0, statement=4)] == ["grasp(PEG)"]
    assert coordinator.marking == {"HOLDING(PEG)", "PEGINHOLE(PEG,HOLE1)", "HOLEEMPTY(HOLE2)"}
    assert (coordinator.actions[0].t, coordinator.actions[0].statement) == (2.0, 4)


def test_contact_needs_the_faces_within_the_tolerance(cell, space) -> None:
    world = ObjectWorld(cell)
    contacts = ContactModel(space, cell)
    peg = world.world_T_object("peg")
    hole2 = cell.features["HOLE2"].world_T_feature
    for lift_mm, inside in ((0.0, True), (0.4, True), (0.6, False), (5.0, False)):
        pose = hole2 @ np.linalg.inv(cell.features["HOLE1"].world_T_feature) @ peg
        pose[2, 3] += 0.030 + lift_mm * 1e-3  # the foot lift_mm above HOLE2's mouth
        world.place("peg", pose)
        truth = contacts.evaluate(CellState.of_world(world, np.eye(4)), ["PEGINHOLE(PEG,HOLE2)", "HOLEEMPTY(HOLE2)"])
        assert truth == {"PEGINHOLE(PEG,HOLE2)": inside, "HOLEEMPTY(HOLE2)": not inside}, lift_mm


def test_any_subset_of_atoms_reads_as_the_full_evaluation_whatever_was_asked_before(cell, space) -> None:
    """evaluate() keeps its face pairs planned per set of atoms and individuals present: on many
    states, asked in a shuffled order of subsets (plans reused, some states without the peg),
    every answer equals the full evaluation of a model that never saw another question."""
    rng = np.random.default_rng(7)
    world = ObjectWorld(cell)
    peg = world.world_T_object("peg")
    hole1, hole2 = (cell.features[h].world_T_feature for h in ("HOLE1", "HOLE2"))
    atoms = list(space.atom_texts)
    kept = ContactModel(space, cell)
    seen = set()
    for k in range(120):
        pose = (hole2 @ np.linalg.inv(hole1) if k % 2 else np.eye(4)) @ peg
        pose[:3, 3] += rng.normal(0.0, 0.004, 3) * (k % 3 != 0)
        world.place("peg", pose)
        tcp = pose.copy()
        tcp[:3, 3] += rng.normal(0.0, 0.02, 3) * (k % 4 != 0)
        state = CellState.of_world(world, tcp)
        if k % 5 == 0:  # the peg's pose unknown on this side: its faces drop out
            state = CellState(state.world_T_tcp, bool(rng.integers(2)), {})
        else:
            state = CellState(state.world_T_tcp, bool(rng.integers(2)), state.world_T_objects)
        full = ContactModel(space, cell).evaluate(state)
        subset = [a for a in atoms if rng.random() < 0.5] or atoms[:1]
        rng.shuffle(subset)
        assert kept.evaluate(state, subset) == {a: full[a] for a in subset}, k
        assert kept.evaluate(state) == full, k
        seen.add(tuple(sorted(a for a, v in full.items() if v)))
    assert len(seen) >= 3  # the states really differ in what holds


@pytest.mark.parametrize("edit, message", [
    ('pre = ["HOLDING(p)", "PEGINHOLE(p, h)"]', "predicate 'BOGUS'"),
    ('del = ["HOLEEMPTY(h)"]', "DEL 'HOLEEMPTY(h)' is not in PRE"),
    ('kind = "peg", object = "peg"', "kind 'gear'"),
])
def test_a_bad_task_file_is_one_error_naming_what_is_wrong(tmp_path, edit, message) -> None:
    text = TASK.read_text()
    bad = {
        'pre = ["HOLDING(p)", "PEGINHOLE(p, h)"]': 'pre = ["HOLDING(p)", "BOGUS(p, h)"]',
        'del = ["HOLEEMPTY(h)"]': 'del = ["HOLDING(p)", "HOLEEMPTY(h)"]\npre_x = 1',
        'kind = "peg", object = "peg"': 'kind = "gear", object = "peg"',
    }[edit]
    if edit.startswith("del"):
        text = text.replace('pre = ["HOLDING(p)", "HOLEEMPTY(h)"]\ndel = ["HOLEEMPTY(h)"]', 'pre = ["HOLDING(p)"]\ndel = ["HOLEEMPTY(h)"]')
    else:
        text = text.replace(edit, bad, 1)
    path = tmp_path / "task.toml"
    path.write_text(text)
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_task_space(path)


def test_net_recognise_prints_the_actions_and_the_net_as_json(tmp_path) -> None:
    out_net = tmp_path / "task.pnml"
    proc = subprocess.run(
        [sys.executable, "-m", "server.cli", "net", "recognise", "assets/programs/peg_transfer.tp",
         "--cell", "assets/cells/peg_in_hole.toml", "--json", "--save", str(out_net)],
        capture_output=True, text=True, timeout=180, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["actions"] == TRANSFER
    assert [p["predicate"] for p in data["net"]["places"]] == TABLE_3_2
    assert data["net"]["transitions"][0] == {"id": "T1", "action": "grasp(PEG)", "pre": ["P1", "P2"], "post": ["P3"]}
    assert data["net"]["initial_marking"] == ["P1", "P2", "P4", "P6"]
    # the saved net opens as a net again and checks as a safe one
    check = subprocess.run([sys.executable, "-m", "server.cli", "net", "check", str(out_net), "--json"],
                           capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert check.returncode == 0, check.stderr
    assert json.loads(check.stdout)["safe"] is True
    bad = subprocess.run([sys.executable, "-m", "server.cli", "net", "recognise", "assets/programs/peg_transfer.tp",
                          "--cell", "assets/cells/puma562_empty.toml"], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert bad.returncode != 0 and "Traceback" not in bad.stderr and bad.stderr.count("\n") == 1
