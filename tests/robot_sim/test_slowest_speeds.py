"""The telerobot runs the slowest speeds the language allows to their end (no division by zero
in its planner or executor), and its settings cannot hold a speed the statements would refuse."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from robot_sim.executor import Executor
from robot_sim.settings import ExecutorSettings, WorldSettings
from robot_sim.worlds import make_world
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_program
from shared.wire.messages import StatementState

CELL = load_cell(DEFAULT_CELL)


@pytest.mark.parametrize("engine", ["kinematic", "physics"])
def test_the_slowest_allowed_speeds_run_to_their_end(engine: str) -> None:
    ex = Executor(CELL, make_world(CELL, WorldSettings(engine=engine, force_noise=0.0)))
    j1 = float(np.degrees(ex.q[0]))
    program = parse_program(
        f"DRIVE J1 TO {j1 + 0.02:.4f} deg WITH SPEED 0.1 deg/s\n"
        "SPEED 0.1 %\n"
        f"DRIVE J1 TO {j1:.4f} deg\n"
        "DRAW TO (0, 0, 0.02) mm IN TOOL WITH SPEED 0.1 mm/s\n"
    )
    assert program.ok, program.error_lines()
    for number, statement in enumerate(program.statements, start=1):
        ex.enqueue(number, statement)
    finals = {}
    for _ in range(int(5.0 * ex.settings.servo_rate)):
        finals.update({e.number: e for e in ex.tick() if e.state.final})
        if len(finals) == len(program.statements):
            break
    assert {n: e.state for n, e in finals.items()} == {n: StatementState.DONE for n in (1, 2, 3, 4)}, finals
    assert np.all(np.isfinite(ex.q))


def test_the_executors_own_speeds_stay_within_the_statement_bounds() -> None:
    with pytest.raises(ValidationError, match="guarded_speed"):
        ExecutorSettings(guarded_speed=1e-9)
    with pytest.raises(ValidationError, match="task_speed"):
        ExecutorSettings(task_speed=1e-9)
