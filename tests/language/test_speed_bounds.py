"""Speeds too slow to finish in a working day are refused where a statement enters (issue 36):
the text form at the number's column, the statement models (so the JSON form and the wire's
units too), with the bound and its unit named. The bounds keep every motion they allow within
``MAX_MOTION_S``: the longest joint travel at the slowest angular speed takes half of it."""

from __future__ import annotations

import json
import math

import pytest
from pydantic import ValidationError

from shared.language import bounds
from shared.language.parser import parse_json, parse_program, parse_statement
from shared.language.statements import SPEED_BOUND, SPEED_MIN, Speed, SpeedUnit, statement_adapter
from shared.errors import InputError


def test_the_slowest_speeds_finish_the_longest_joint_travel_within_a_working_day() -> None:
    longest = 2 * bounds.MAX_ANGLE_RAD  # from -720 deg to 720 deg
    assert longest / bounds.MIN_ANGULAR_SPEED_RAD_S <= bounds.MAX_MOTION_S / 2
    assert bounds.MAX_MOTION_S == 8 * 3600.0
    assert bounds.MAX_TIME_S <= bounds.MAX_MOTION_S
    for unit in SpeedUnit:
        assert 0 < SPEED_MIN[unit] < SPEED_BOUND[unit]


@pytest.mark.parametrize("text, number, says", [
    ("DRAW TO (600, 0, 300) mm WITH SPEED 1e-300 mm/s", "1e-300", "speed = 1e-300 mm/s is below the slowest speed bound of 0.1 mm/s"),
    ("MOVES TO (600, 0, 300) mm (180, 0, 0) deg WITH SPEED 0.05 mm/s", "0.05", "slowest speed bound of 0.1 mm/s"),
    ("SPEED 1e-300 %", "1e-300", "speed = 1e-300 % is below the slowest speed bound of 0.1 %"),
    ("SPEED 0.09 %", "0.09", "slowest speed bound of 0.1 %"),
    ("DRIVE J1 TO 10 deg WITH SPEED 0.01 deg/s", "0.01", "slowest speed bound of 0.1 deg/s"),
    ("MOVE (0, 0, 0, 0, 0, 0) deg WITH SPEED 1e-300 deg/s", "1e-300", "slowest speed bound of 0.1 deg/s"),
])
def test_the_text_form_refuses_a_speed_below_the_slowest_bound_at_its_column(text: str, number: str, says: str) -> None:
    col = text.rindex(number) + 1
    with pytest.raises(InputError, match=f"column {col}: .*below") as exc:
        parse_statement(text)
    assert says in str(exc.value) and "8 h" in str(exc.value)
    parsed = parse_program(text + "\n", "slow.tp")
    assert not parsed.ok and parsed.error_lines()[0].startswith(f"slow.tp:1:{col}: ")


@pytest.mark.parametrize("text", ["SPEED 0.1 %", "DRAW TO (600, 0, 300) mm WITH SPEED 0.1 mm/s",
                                  "DRIVE J1 TO 10 deg WITH SPEED 0.1 deg/s", "SPEED 100 %"])
def test_the_slowest_and_fastest_speeds_themselves_are_taken(text: str) -> None:
    parse_statement(text)


@pytest.mark.parametrize("value, unit", [(5e-324, "rad/s"), (1e-300, "m/s"), (1e-5, "fraction"),
                                         (SPEED_MIN[SpeedUnit.M_PER_S] / 2, "m/s")])
def test_the_models_refuse_a_speed_below_the_slowest_bound_with_it_named(value: float, unit: str) -> None:
    with pytest.raises(ValidationError, match="below the slowest speed bound of"):
        Speed(value=value, unit=unit)
    statement = {"kind": "DRIVE", "joint": 1, "target": 0.5, "speed": {"value": value, "unit": unit}}
    with pytest.raises(ValidationError, match="DRIVE.speed"):
        statement_adapter.validate_python(statement)
    parsed = parse_json(json.dumps([statement]), "slow.json")
    assert not parsed.ok
    line = parsed.error_lines()[0]
    assert line.startswith("slow.json: /0/speed: ") and "below the slowest speed bound" in line and "\n" not in line


def test_the_wire_refuses_a_speed_below_the_slowest_bound_before_the_robot_plans_it() -> None:
    """A unit carrying 5e-324 rad/s (which reached the robot and divided by zero: "internal
    error") is rejected with the bound named."""
    from robot_sim.core import RobotCore
    from robot_sim.executor import Executor
    from robot_sim.settings import WorldSettings
    from robot_sim.worlds import make_world
    from shared.cells.loader import DEFAULT_CELL, load_cell
    from shared.language.statements import Drive
    from shared.wire.messages import Hello, Rejected, RejectReason, encode_message
    from shared.wire.units import encode_unit

    cell = load_cell(DEFAULT_CELL)
    core = RobotCore(Executor(cell, make_world(cell, WorldSettings(engine="kinematic"))), session_id="unit")
    core.connect()
    core.on_text(encode_message(Hello(client_id="c")))
    slow = Speed.model_construct(value=5e-324, unit=SpeedUnit.RAD_PER_S)
    unit = encode_unit(1, 0, [Drive.model_construct(kind="DRIVE", joint=1, target=0.5, speed=slow, until=None)], True)
    [reply] = core.on_unit(unit)
    assert isinstance(reply, Rejected) and reply.reason is RejectReason.INVALID_STATEMENT
    assert "slowest speed bound" in reply.detail and "internal error" not in reply.detail


def test_until_time_is_bounded_by_an_hour() -> None:
    with pytest.raises(InputError, match="time bound"):
        parse_statement(f"DRIVE J1 TO 10 deg UNTIL TIME {bounds.MAX_TIME_S + 1:g} s")
    assert math.isclose(parse_statement("DRIVE J1 TO 10 deg UNTIL TIME 3600 s").until.seconds, 3600.0)
