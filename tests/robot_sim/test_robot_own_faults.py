"""The surprises the fault campaigns found the robot blind to, each now a stop with a reason: a wrist
sensor that drops out (moving or idle), a joint that drags the arm off its servo, fingers that close
past the object, and a heavier object than modelled (the robot tares for the model's mass)."""

from __future__ import annotations

import numpy as np

from robot_sim.core import RobotCore
from robot_sim.executor import SENSOR_INVALID, Executor
from robot_sim.physics import faults as world_faults
from robot_sim.settings import WorldSettings
from robot_sim.worlds import make_world
from server.trials.programs import transfer_program
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_statement
from shared.wire.messages import Halted, HaltCause, RobotState, StatementState, encode_message
from shared.wire.session import CommandSender

CELL = load_cell(DEFAULT_CELL)
PROGRAM = transfer_program(DEFAULT_CELL)
FINAL = {StatementState.DONE, StatementState.FAILED, StatementState.SKIPPED, StatementState.ABORTED}
FAR_MOVE = "MOVES TO (0, 80, 160) mm (180, 0, 0) deg IN WORK"


def executor(**world) -> Executor:
    return Executor(CELL, make_world(CELL, WorldSettings(**world)))


def run_texts(ex: Executor, texts: list[str], first: int = 1, seconds: float = 120.0) -> dict[int, object]:
    for number, text in enumerate(texts, start=first):
        ex.enqueue(number, parse_statement(text))
    return {e.number: e for e in ex.run_until_idle(seconds) if e.state in FINAL}


def under_way(ex: Executor, number: int = 10) -> None:
    ex.enqueue(number, parse_statement(FAR_MOVE))
    for _ in range(30):
        ex.tick()
    assert ex.state is RobotState.RUNNING


def test_a_sensor_dropout_mid_motion_fails_the_statement_and_holds() -> None:
    ex = executor()
    under_way(ex)
    world_faults.sensor_dropout(ex.world)
    events = [e for _ in range(3) for e in ex.tick()]
    failed = [e for e in events if e.state is StatementState.FAILED]
    assert failed and failed[0].reason == SENSOR_INVALID
    assert ex.state is RobotState.FAULT
    assert all(np.isfinite(v) for v in failed[0].snapshot.wrench)  # the report still encodes: numbers, and the reason says why


def test_a_sensor_dropout_while_idle_halts_the_robot_with_its_cause() -> None:
    core = RobotCore(executor())
    core.connect()
    core.on_text(encode_message(CommandSender("test").hello()))
    for _ in range(5):
        core.tick()
    assert core.executor.state is RobotState.IDLE
    world_faults.sensor_dropout(core.executor.world)
    out = [m for _ in range(3) for m in core.tick()]
    halts = [m for m in out if isinstance(m, Halted)]
    assert [h.cause for h in halts] == [HaltCause.SENSOR_FAULT]
    assert core.executor.state is RobotState.FAULT


def test_a_dragging_joint_in_free_motion_stops_on_the_following_error() -> None:
    ex = executor()
    under_way(ex)
    world_faults.drag_joint(ex.world, 0, 250.0)  # the servo holds a smaller drag within its band
    failed = []
    for _ in range(50):
        failed += [e for e in ex.tick() if e.state is StatementState.FAILED]
        if failed:
            break
    assert failed and "does not follow its servo" in failed[0].reason
    flange = CELL.robot.fk(ex.world.q)[:3, 3]
    commanded = CELL.robot.fk(ex.world.target)[:3, 3]
    assert np.linalg.norm(flange - commanded) < 0.02  # it stopped near the band, not after running off


def test_fingers_closing_past_a_missing_peg_fail_the_grasp_before_the_gripper_time() -> None:
    ex = executor()
    done = run_texts(ex, PROGRAM.texts("approach", "grasp")[:-1])
    assert all(e.state is StatementState.DONE for e in done.values())
    world_faults.remove_object(ex.world, "peg")
    start = ex.time
    done = run_texts(ex, ["TASK grasp(peg)"], first=20)
    assert done[20].state is StatementState.FAILED and "on nothing" in done[20].reason
    assert ex.time - start < ex.settings.gripper_time  # it did not wait the whole closing time


def test_a_heavier_object_is_heavier_in_the_physics_but_not_in_the_robots_model() -> None:
    light = executor(force_noise=0.0)
    heavy = executor(force_noise=0.0, object_mass_factor=3.0)
    b = heavy.world._bodies["peg"]
    assert heavy.world.model.body_mass[b] == np.float64(light.world.model.body_mass[b] * 3.0)
    assert heavy.world.object_mass("peg") == light.world.object_mass("peg")  # what the robot tares for
