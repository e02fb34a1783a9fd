"""The telerobot's executor in virtual time on the kinematic world (``robot_sim.world``, fast and
exact): the peg transfer, force-guided search, surprises and recovery, and the rule that every
statement ends in exactly one final state. What the contact physics makes happen (sticking,
jamming, a lost peg, the wrist's reading, stopping the physical arm) is tested on the physics
world in ``test_physics_world``."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from robot_sim.executor import Executor, ExecutorEvent
from robot_sim.world import SimWorld, WorldSettings
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_program
from shared.paths import ASSETS_DIR
from shared.wire.messages import RobotState, StatementState

CELL = load_cell(DEFAULT_CELL)
PEG_TRANSFER = parse_program((ASSETS_DIR / "programs" / "peg_transfer.tp").read_text()).statements
FINAL = {StatementState.DONE, StatementState.FAILED, StatementState.SKIPPED, StatementState.ABORTED}


def make(program, **world) -> Executor:
    ex = Executor(CELL, SimWorld(CELL, CELL.robot, WorldSettings(**world)))
    for number, statement in enumerate(program, start=1):
        ex.enqueue(number, statement)
    return ex


def finals(events: list[ExecutorEvent]) -> dict[int, ExecutorEvent]:
    out: dict[int, ExecutorEvent] = {}
    for e in events:
        if e.state in FINAL:
            assert e.number not in out, f"statement {e.number} got a second final status"
            out[e.number] = e
    return out


def peg_xy_error(ex: Executor, hole: str) -> float:
    peg = ex.world.pegs["peg"]
    return float(np.linalg.norm(peg.world_T_peg[:2, 3] - ex.world.holes[hole].world_T_hole[:2, 3]))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_peg_transfer_moves_the_peg_into_hole2(seed: int) -> None:
    ex = make(PEG_TRANSFER, seed=seed)
    events = ex.run_until_idle()
    done = finals(events)
    assert sorted(done) == list(range(1, len(PEG_TRANSFER) + 1))
    assert all(e.state is StatementState.DONE for e in done.values()), [e.reason for e in done.values()]
    # each statement was reported running once, before its final state
    running = Counter(e.number for e in events if e.state is StatementState.RUNNING)
    assert set(running.values()) == {1}
    peg = ex.world.pegs["peg"]
    assert peg.in_hole == "HOLE2" and not peg.held
    # the real hole is offset from the model; the peg sits in the real one
    assert peg_xy_error(ex, "HOLE2") < 0.0015
    floor = ex.world.holes["HOLE2"].world_T_hole[2, 3] - ex.world.settings.hole_depth
    assert abs(peg.world_T_peg[2, 3] - peg.half_size[2] - floor) < 1e-4
    assert ex.state is RobotState.IDLE


def test_a_hole_far_from_the_model_is_found_by_the_force_search() -> None:
    """3 mm offsets exceed the 1.5 mm capture of the hole mouth: only the search finds it."""
    quick = make(PEG_TRANSFER, seed=4, object_offset=0.0)
    quick.run_until_idle()
    ex = make(PEG_TRANSFER, seed=4, object_offset=0.003)
    hole = ex.world.holes["HOLE2"].world_T_hole[:2, 3] - CELL.features["HOLE2"].world_T_feature[:2, 3]
    assert np.max(np.abs(hole)) > ex.world.settings.chamfer  # the premise of this test
    done = finals(ex.run_until_idle())
    assert done[12].state is StatementState.DONE and "seated" in done[12].reason
    assert ex.world.pegs["peg"].in_hole == "HOLE2"
    assert ex.time > quick.time  # the search took extra motion


def test_unplanned_contact_stops_the_arm_and_resume_goes_on() -> None:
    program = parse_program(
        "\n".join(
            [
                "MOVES TO (0, -80, 160) mm (180, 0, 0) deg IN WORK",
                "DRAW TO (0, -80, 75) mm IN WORK",
                "TASK grasp(peg)",
                "TASK extract_peg(peg, HOLE1)",
                "DRAW TO (0, -30, 120) mm IN WORK",
                "DRAW TO (0, -30, 60) mm IN WORK",  # drives the peg into the plate top
                "DRAW TO (0, -30, 140) mm IN WORK",
            ]
        )
    ).statements
    ex = make(program, seed=2)
    done = finals(ex.run_until_idle())
    assert done[6].state is StatementState.FAILED and "unplanned contact" in done[6].reason
    assert ex.state is RobotState.FAULT and 7 not in done
    assert ex.resume()[0]
    done.update(finals(ex.run_until_idle()))
    assert done[7].state is StatementState.DONE
    tcp = ex.world.world_T_tcp(ex.q)
    work_z = (np.linalg.inv(CELL.frame("work")) @ tcp)[2, 3]
    assert abs(work_z - 0.140) < 1e-4


def test_stop_freezes_the_motion_resume_finishes_it_skip_drops_it() -> None:
    program = parse_program(
        "MOVE (0, -45, 180, 0, 45, 0) deg\nMOVE (30, -45, 180, 0, 45, 0) deg\nMOVE (0, -45, 180, 0, 45, 0) deg"
    ).statements
    ex = make(program, seed=1)
    for _ in range(20):
        ex.tick()
    assert ex.current_number == 1
    assert ex.stop()[0] and ex.state is RobotState.STOPPED
    q = ex.q.copy()
    for _ in range(30):
        ex.tick()
    np.testing.assert_array_equal(ex.q, q)
    assert ex.resume()[0]
    events = []
    while ex.current_number != 2:
        events += ex.tick()
    assert finals(events)[1].state is StatementState.DONE
    np.testing.assert_allclose(ex.q, np.radians([0, -45, 180, 0, 45, 0]), atol=1e-9)
    ex.stop()
    assert ex.skip(2)[0]
    events = ex.run_until_idle()  # the skip report comes out with the next tick
    done = finals(events)
    assert done[2].state is StatementState.SKIPPED and done[3].state is StatementState.DONE
    assert not ex.skip(3)[0]  # nothing current any more


def test_a_refused_plan_fails_its_statement_with_the_reason() -> None:
    program = parse_program("DRAW TO (3000, 0, 0) mm IN BASE\nEVENT after").statements
    ex = make(program)
    done = finals(ex.run_until_idle())
    assert done[1].state is StatementState.FAILED and "reach" in done[1].reason.lower()
    assert ex.state is RobotState.FAULT and 2 not in done


def test_the_rover_stops_where_its_arm_meets_the_terrain() -> None:
    rover = load_cell(ASSETS_DIR / "cells" / "rover_terrain.toml")
    ex = Executor(rover, SimWorld(rover, rover.robot, WorldSettings()))
    # a joint move that swings the arm down onto the ground (its end lies on the terrain)
    for number, statement in enumerate(parse_program("MOVE (-40, -40, -200) deg").statements, start=1):
        ex.enqueue(number, statement)
    done = finals(ex.run_until_idle())
    assert done[1].state is StatementState.FAILED and "touches the terrain" in done[1].reason
    assert ex.state is RobotState.FAULT
    # it holds at the last servo step clear of the ground: short of the goal, just not touching
    # (the step into contact is never commanded, so a motion away starts clear)
    from shared.terrain.cell import load_cell_terrain

    checker = load_cell_terrain(rover).checker
    assert 0.0 < checker.min_distance(ex.q) < 0.005
    assert np.max(np.abs(ex.q - np.radians([-40.0, -40.0, -200.0]))) > np.radians(0.5)


@pytest.mark.parametrize("where", ["running", "stopped mid-motion", "stopped with a queue", "fault"])
def test_abort_returns_the_robot_to_idle_and_a_new_statement_runs(where: str) -> None:
    """Abort from each state it is offered in drops the current statement and the buffer, leaves
    the robot IDLE with nothing held, and the next statement sent starts and finishes."""
    slow = "SPEED 5 %"
    away = "MOVE (20, -45, 180, 0, 45, 0) deg"
    home = "MOVE (0, -45, 180, 0, 45, 0) deg"
    text = "DRIVE J9 TO 0 deg\nEVENT next\nEVENT after" if where == "fault" else "\n".join([slow, away, home, away])
    parsed = parse_program(text)
    assert not parsed.errors, parsed.errors
    program = parsed.statements
    ex = make(program, seed=1)
    events: list[ExecutorEvent] = []
    if where == "fault":
        for _ in range(3):
            events += ex.tick()
        assert ex.state is RobotState.FAULT  # the premise: joint 9 does not exist
    elif where == "stopped with a queue":
        ex.stop()
        assert ex.current is None and len(ex.queue) == len(program)
    else:
        for _ in range(20):
            events += ex.tick()
        assert ex.current_number == 2 and ex.state is RobotState.RUNNING  # the premise: mid-motion
        if where == "stopped mid-motion":
            ex.stop()
            assert ex.state is RobotState.STOPPED
    assert ex.queue  # something is still waiting in the buffer

    applied, _ = ex.abort()
    assert applied
    assert ex.state is RobotState.IDLE
    assert ex.current is None and not ex.queue and not ex.busy and ex.halted is None
    events += ex.drain_events()
    done = finals(events)
    assert sorted(done) == list(range(1, len(program) + 1))  # every statement got its one final state
    dropped = [n for n, e in done.items() if e.state is StatementState.ABORTED]
    assert dropped and dropped == list(range(min(dropped), len(program) + 1))

    # the robot takes and runs a new statement after the abort, without resume
    number = len(program) + 1
    ex.enqueue(number, parse_program("MOVE (5, -45, 180, 0, 45, 0) deg").statements[0])
    after = finals(ex.run_until_idle(max_seconds=60.0))
    assert after[number].state is StatementState.DONE, after[number].reason
    assert ex.state is RobotState.IDLE
    np.testing.assert_allclose(ex.q, np.radians([5, -45, 180, 0, 45, 0]), atol=1e-9)
