"""The telerobot's physics world (MuJoCo): the model is the console's robot, the sensors read what
the contact does, and sticking, jamming and losing a peg come out of the physics, never a coin."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from robot_sim.executor import Executor
from robot_sim.physics.world import PhysicsWorld
from robot_sim.settings import WorldSettings
from robot_sim.worlds import make_world
from server.trials.programs import transfer_program
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.errors import FileFormatError
from shared.language.parser import parse_statement
from shared.wire.messages import RobotState, StatementState

CELL = load_cell(DEFAULT_CELL)
PROGRAM = transfer_program(DEFAULT_CELL)
FINAL = {StatementState.DONE, StatementState.FAILED, StatementState.SKIPPED, StatementState.ABORTED}


def run(texts: list[str], seconds: float = 120.0, **world) -> tuple[Executor, dict[int, object]]:
    ex = Executor(CELL, make_world(CELL, WorldSettings(**world)))
    for number, text in enumerate(texts, start=1):
        ex.enqueue(number, parse_statement(text))
    done = {e.number: e for e in ex.run_until_idle(seconds) if e.state in FINAL}
    return ex, done


def test_the_default_world_is_physics_and_the_arm_is_the_consoles_robot() -> None:
    world = make_world(CELL)
    assert isinstance(world, PhysicsWorld) and world.engine == "mujoco"
    rng = np.random.default_rng(3)
    import mujoco

    for _ in range(5):  # the MJCF chain is the pinocchio model's: same tool pose at any joint vector
        q = rng.uniform(CELL.robot.lower, CELL.robot.upper)
        world.data.qpos[world._qadr] = q
        world.data.qpos[world._qadr.max() + 1:world._qadr.max() + 6] = 0.0  # the compliant wrist at rest
        mujoco.mj_kinematics(world.model, world.data)
        expected = CELL.world_T_base @ CELL.robot.fk(q) @ CELL.flange_T_tcp
        np.testing.assert_allclose(world.world_T_tcp()[:3, 3], expected[:3, 3], atol=1e-6)
        np.testing.assert_allclose(world.world_T_tcp()[:3, :3], expected[:3, :3], atol=1e-6)
    assert "Armstrong" in world.layout.inertia_source  # the PUMA's published inertias


def test_the_held_peg_at_rest_reads_its_weight_on_the_wrist() -> None:
    ex, done = run(PROGRAM.texts("approach", "grasp", "extract"), force_noise=0.0)
    assert all(e.state is StatementState.DONE for e in done.values()), [e.reason for e in done.values()]
    for _ in range(100):
        ex.tick()
    weight = 9.81 * ex.world.object_mass("peg")
    assert weight > 1.0  # a 20 x 20 x 80 mm steel peg: about 2.5 N
    assert ex.wrench[2] == pytest.approx(-weight, rel=0.02)
    assert np.linalg.norm(ex.wrench[:2]) < 0.02 * weight


def test_stop_halts_the_physical_arm_within_one_servo_period() -> None:
    ex, _ = run(PROGRAM.texts("approach")[:1])
    ex.enqueue(10, parse_statement("MOVES TO (0, 80, 160) mm (180, 0, 0) deg IN WORK"))
    for _ in range(40):
        ex.tick()
    speed = float(np.max(np.abs(ex.world.qd)))
    assert ex.state is RobotState.RUNNING and speed > 0.1  # well under way
    ex.stop()
    ex.tick()
    assert float(np.max(np.abs(ex.world.qd))) < 0.01 * speed
    q_stop = ex.world.q
    for _ in range(30):
        ex.tick()
    flange = lambda q: CELL.robot.fk(q)[:3, 3]  # noqa: E731
    assert np.linalg.norm(flange(ex.world.q) - flange(q_stop)) < 1e-4
    assert ex.state is RobotState.STOPPED


def test_the_peg_transfer_ends_with_the_physical_peg_in_hole2() -> None:
    ex, done = run(PROGRAM.texts(), seed=2, object_offset=0.002)
    assert all(e.state is StatementState.DONE for e in done.values()), [e.reason for e in done.values()]
    peg = ex.world.pegs["peg"]
    assert peg.in_hole == "HOLE2" and not peg.held
    hole = ex.world.holes["HOLE2"]
    foot = peg.world_T_peg[2, 3] - peg.half_size[2]
    assert foot == pytest.approx(hole.world_T_hole[2, 3] - hole.depth, abs=2e-4)  # on the real hole's floor


def test_high_friction_makes_the_peg_stick_and_the_robot_waits_for_the_operator() -> None:
    # seed 1 puts the plate 2 mm off across the fingers: closing them presses the peg on its hole's
    # wall through the compliant wrist, and dry friction holds it past the extraction's 40 N
    ex, done = run(PROGRAM.texts("approach", "grasp", "extract", "carry"), seed=1, object_offset=0.002, friction=0.6)
    failed = [e for e in done.values() if e.state is StatementState.FAILED]
    assert len(failed) == 1 and "stuck" in failed[0].reason
    assert ex.state is RobotState.FAULT and ex.world.pegs["peg"].in_hole == "HOLE1"
    flange = CELL.robot.fk(ex.world.q)[:3, 3]
    for _ in range(50):  # nothing moves while the robot waits (beyond the pull relaxing)
        ex.tick()
    assert np.linalg.norm(CELL.robot.fk(ex.world.q)[:3, 3] - flange) < 5e-4


def test_a_tilted_grasp_jams_the_insertion() -> None:
    _, done = run(PROGRAM.texts("approach", "grasp", "extract", "carry", "insert"), seed=1, grasp_tilt=math.radians(2.0))
    last = done[max(done)]
    assert last.state is StatementState.FAILED and "jammed" in last.reason


def test_the_robot_notices_a_peg_lost_from_the_gripper() -> None:
    ex = Executor(CELL, make_world(CELL, WorldSettings(seed=0)))
    for number, text in enumerate(PROGRAM.texts("approach", "grasp", "extract"), start=1):
        ex.enqueue(number, parse_statement(text))
    ex.run_until_idle(120)
    ex.enqueue(10, parse_statement("DRAW TO (0, -80, 200) mm IN WORK WITH SPEED 30 mm/s"))
    for _ in range(20):
        ex.tick()
    world = ex.world
    world.model.actuator_forcerange[world._grip[0]] = (-0.3, 0.3)  # the grip weakens: 0.3 N cannot hold 2.5 N
    events = ex.run_until_idle(10)
    failed = [e for e in events if e.state is StatementState.FAILED]
    assert failed and "lost from the gripper" in failed[0].reason
    assert ex.world.held_peg() is None


def test_an_unstable_simulation_stops_the_robot_with_a_reason() -> None:
    ex = Executor(CELL, make_world(CELL))
    ex.enqueue(1, parse_statement("MOVES TO (0, 80, 160) mm (180, 0, 0) deg IN WORK"))
    ex.tick()
    ex.world.data.qvel[0] = np.nan  # the simulation blows up
    events = ex.run_until_idle(5)
    assert ex.state is RobotState.FAULT
    failed = [e for e in events if e.state is StatementState.FAILED]
    assert failed and "unstable" in failed[0].reason
    for _ in range(50):  # the world went back to its last stable state and holds there
        ex.tick()
    assert np.all(np.isfinite(ex.world.data.qpos)) and float(np.max(np.abs(ex.world.qd))) < 1e-2


def test_a_world_at_rest_lets_time_pass_without_steps() -> None:
    world = make_world(CELL)
    world.settle(0.5)
    assert world.asleep
    steps = world.steps
    for _ in range(100):
        world.servo(world.target)
    assert world.steps == steps and world.skipped_steps >= 1000
    world.servo(world.target + 0.01)  # a new setpoint wakes it
    assert world.steps > steps and not world.asleep


def test_a_resting_peg_sleeps_while_the_arm_moves_and_is_still_read_where_it_is(monkeypatch) -> None:
    worlds = {}
    for sleep in (True, False):
        monkeypatch.setattr(PhysicsWorld, "SLEEP", sleep)
        world = make_world(CELL, WorldSettings(seed=2, object_offset=0.002))
        q = world.target
        for k in range(60):  # the arm swings over the cell, the peg stays in its hole
            world.servo(q + np.array([0.2, -0.1, 0.1, 0.2, 0.1, 0.1]) * (k / 60))
        worlds[sleep] = world
    sleeping, awake = worlds[True], worlds[False]
    tree = sleeping._object_tree["peg"]
    assert not sleeping.data.tree_awake[tree] and awake.data.tree_awake[tree]
    assert sleeping.pegs["peg"].in_hole == awake.pegs["peg"].in_hole == "HOLE1"
    # asleep, the peg stops where it fell asleep; awake, it sinks on into its soft contact by a
    # micrometre or so (a sixth of the thesis's 0.03 mm clearance is the bound)
    np.testing.assert_allclose(sleeping.pegs["peg"].world_T_peg, awake.pegs["peg"].world_T_peg, atol=5e-6)
    np.testing.assert_allclose(sleeping.q, awake.q, atol=1e-9)  # the arm's motion is the same


@pytest.mark.parametrize(("table", "field"), [
    ("friction = -0.1", "physics.friction"),
    ("clearance_mm = -0.01", "physics.clearance_mm"),
    ("timestep_ms = 0", "physics.timestep_ms"),
    ("stiffness = 3", "physics.stiffness"),
    ("friction = \"much\"", "physics.friction"),
])
def test_a_wrong_physics_table_is_refused_with_the_file_and_field(tmp_path: Path, table: str, field: str) -> None:
    path = tmp_path / "cell.toml"
    path.write_text(Path(DEFAULT_CELL).read_text() + f"\n[physics]\n{table}\n")
    with pytest.raises(FileFormatError) as err:
        load_cell(path)
    assert str(path) in str(err.value) and field in str(err.value)


def test_a_peg_wider_than_its_hole_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "cell.toml"
    path.write_text(Path(DEFAULT_CELL).read_text().replace("size = [20.0, 20.0, 80.0]", "size = [20.05, 20.0, 80.0]"))
    with pytest.raises(FileFormatError) as err:
        make_world(load_cell(path))
    assert str(path) in str(err.value) and "wider than its hole" in str(err.value)


def test_the_clearance_setting_fits_the_peg_to_its_hole() -> None:
    world = make_world(CELL, WorldSettings(clearance=0.0002))
    assert world.clearance("peg") == pytest.approx(0.0002, abs=1e-7)
    assert make_world(CELL).clearance("peg") == pytest.approx(0.00003, abs=1e-7)  # the file's 20.03 / 20.00 mm
