"""Properties: the parser never crashes on any input, and text <-> JSON round-trips exactly."""

from __future__ import annotations

import json
import math
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shared.language import bounds
from shared.language.formatter import format_program, format_statement
from shared.language.parser import parse_json, parse_program
from shared.language.statements import (
    ACTION_KINDS,
    PARAMETER_KINDS,
    SPEED_BOUND,
    SPEED_MIN,
    TASK_KINDS,
    Draw,
    Drive,
    Event,
    Frame,
    Mode,
    Move,
    Moves,
    Rotate,
    SetMode,
    SetSpeed,
    Speed,
    SpeedUnit,
    TaskCall,
    UntilContact,
    UntilForce,
    UntilTime,
    program_to_json,
)
from shared.language.units import TextUnit, from_si, to_si

PROGRAMS = Path(__file__).resolve().parents[2] / "assets" / "programs"
SEED_TEXT = (PROGRAMS / "peg_transfer.tp").read_text() + (PROGRAMS / "rover_placement.tp").read_text() + (
    "DRIVE J3 TO -30 deg WITH SPEED 20 %\nROTATE TO (1, 2, 3) deg IN TOOL UNTIL FORCE > 5 N\n"
    "MOVES TO (1e2, -2.5, .3) mm (4, 5, 6) deg UNTIL TIME 2 s WITH SPEED 3 deg/s\n"
)

# -- fuzz -------------------------------------------------------------------------------------
ALPHABET = st.sampled_from(list("()%,>#/.+-eE_ \t\r\n0123456789") + ["J", "x", "\x00", "\u00e9", "\u3000"])
WORDS = st.sampled_from(
    ["MOVE", "DRIVE", "DRAW", "ROTATE", "MOVES", "SPEED", "MODE", "EVENT", "TASK", "TO", "IN", "WITH", "UNTIL",
     "FORCE", "CONTACT", "TIME", "deg", "mm", "mm/s", "deg/s", "N", "s", "%", "WORK", "TOOL", "J3", "(", ")", ",",
     ">", "1", "-2.5e3", "1e999", "#", "\n"]
)


def _check_result(text: str) -> None:
    result = parse_program(text, "fuzz.tp")
    n_lines = text.count("\n") + 1
    for err in result.errors:
        assert 1 <= err.line <= n_lines
        assert err.col >= 1
        assert err.message
    assert len(result.statements) == len(result.lines)
    # whatever parsed, formats and parses back to the same JSON
    again = parse_program(format_program(result.statements))
    assert again.ok
    assert program_to_json(again.statements) == program_to_json(result.statements)


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet=ALPHABET, max_size=200))
def test_random_text_never_crashes(text: str) -> None:
    _check_result(text)


@settings(max_examples=300, deadline=None)
@given(st.lists(WORDS, max_size=40).map(" ".join))
def test_random_keyword_soup_never_crashes(text: str) -> None:
    _check_result(text)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_mutated_valid_programs_never_crash(data: st.DataObject) -> None:
    text = SEED_TEXT
    for _ in range(data.draw(st.integers(1, 8))):
        pos = data.draw(st.integers(0, len(text)))
        op = data.draw(st.sampled_from(["insert", "delete", "replace"]))
        piece = data.draw(st.text(alphabet=ALPHABET, min_size=1, max_size=4))
        if op == "insert":
            text = text[:pos] + piece + text[pos:]
        elif op == "delete":
            text = text[:pos] + text[pos + len(piece):]
        else:
            text = text[:pos] + piece + text[pos + len(piece):]
    _check_result(text)


@settings(max_examples=100, deadline=None)
@given(st.recursive(st.none() | st.booleans() | st.floats() | st.text(max_size=5),
                    lambda c: st.lists(c, max_size=4) | st.dictionaries(st.sampled_from(["kind", "joints", "name", "x"]), c, max_size=3),
                    max_leaves=12))
def test_random_json_never_crashes(data: object) -> None:
    result = parse_json(json.dumps(data))
    assert result.ok == (result.errors == [])
    if _non_finite(data):  # json.dumps writes NaN or Infinity, which strict JSON refuses: one fault
        assert result.statements == [] and len(result.errors) == 1 and "not a JSON number" in result.errors[0].message
    elif not isinstance(data, list):
        assert result.statements == [] and [e.message for e in result.errors] == ["a JSON program is a list of statement objects"]
    else:  # each item is a statement or has its own errors, pointing into it
        faulty = {e.statement for e in result.errors}
        assert all(e.pointer.startswith(f"/{e.statement}") for e in result.errors)
        assert faulty <= set(range(len(data))) and len(result.statements) + len(faulty) == len(data)
        for i, item in enumerate(data):  # only an object whose kind is a statement's can be one
            assert i in faulty or (isinstance(item, dict) and item.get("kind") in ACTION_KINDS | PARAMETER_KINDS | TASK_KINDS), item


def _non_finite(data: object) -> bool:
    if isinstance(data, float):
        return not math.isfinite(data)
    if isinstance(data, list):
        return any(_non_finite(v) for v in data)
    if isinstance(data, dict):
        return any(_non_finite(v) for v in data.values())
    return False


# -- round trip -------------------------------------------------------------------------------
# any float within the physical bounds of shared.language.bounds (subnormals included)
finite = st.floats(min_value=-bounds.MAX_ANGLE_RAD, max_value=bounds.MAX_ANGLE_RAD, width=64)
small = st.floats(min_value=-10.0, max_value=10.0, allow_nan=False)
angle = st.one_of(small, st.integers(-360, 360).map(math.radians), finite)
positive = st.floats(min_value=1e-9, max_value=bounds.MAX_LINEAR_SPEED_M_S, exclude_min=False).filter(lambda v: v > 0)
vec3 = st.tuples(angle, angle, angle)
name = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,8}", fullmatch=True)
# any speed between the slowest (a working day's motion) and the fastest bound of its unit
speed = st.sampled_from(list(SpeedUnit)).flatmap(
    lambda u: st.floats(min_value=SPEED_MIN[u], max_value=SPEED_BOUND[u]).map(lambda v: Speed(value=v, unit=u)))
until = st.one_of(st.none(), st.builds(UntilForce, newtons=positive), st.just(UntilContact()),
                  st.builds(UntilTime, seconds=positive))
action_extra = {"speed": st.one_of(st.none(), speed), "until": until}
frame = st.sampled_from(list(Frame))

statement = st.one_of(
    st.builds(Move, joints=st.lists(angle, min_size=1, max_size=7).map(tuple), **action_extra),
    st.builds(Drive, joint=st.integers(1, bounds.MAX_JOINTS), target=angle, **action_extra),
    st.builds(Draw, position=vec3, frame=frame, **action_extra),
    st.builds(Rotate, rpy=vec3, frame=frame, **action_extra),
    st.builds(Moves, position=vec3, rpy=vec3, frame=frame, **action_extra),
    st.builds(SetSpeed, speed=speed),
    st.builds(SetMode, mode=st.sampled_from(list(Mode))),
    st.builds(Event, name=name),
    st.builds(TaskCall, name=name, args=st.lists(name, max_size=3).map(tuple)),
)


@settings(max_examples=400, deadline=None)
@given(st.lists(statement, max_size=12))
def test_statements_round_trip_exactly(statements: list) -> None:
    json1 = program_to_json(statements)
    text = format_program(statements)
    parsed = parse_program(text)
    assert parsed.ok, parsed.error_lines()
    assert program_to_json(parsed.statements) == json1
    # and the second lap is a fixed point of the text too
    assert format_program(parsed.statements) == text
    assert json.loads(json.dumps(json1)) == json1


@settings(max_examples=1000, deadline=None)
@given(finite, st.sampled_from(list(TextUnit)))
def test_every_si_float_has_an_exact_text(value: float, unit: TextUnit) -> None:
    text = from_si(value, unit)
    assert to_si(text, unit) == value
    assert math.copysign(1.0, to_si(text, unit)) == math.copysign(1.0, value)


def test_round_numbers_print_short() -> None:
    assert format_statement(Move(joints=(math.radians(30), math.radians(-15.18), 0.0))) == "MOVE (30, -15.18, 0) deg"
    assert format_statement(Draw(position=(0.55, -0.08, 0.45))) == "DRAW TO (550, -80, 450) mm"
    assert format_statement(SetSpeed(speed=Speed(value=0.2, unit=SpeedUnit.FRACTION))) == "SPEED 20 %"


def test_example_text_to_json_to_text_to_json() -> None:
    for path in PROGRAMS.glob("*.tp"):
        first = parse_program(path.read_text())
        assert first.ok, first.error_lines()
        json1 = program_to_json(first.statements)
        text = format_program(first.statements)
        json2 = program_to_json(parse_program(text).statements)
        assert json.dumps(json1) == json.dumps(json2)


def test_formatter_refuses_what_the_text_cannot_hold() -> None:
    import pytest

    from shared.errors import InputError

    # the models refuse these values; a statement built around them is refused by the formatter
    with pytest.raises(InputError, match="not a name"):
        format_statement(TaskCall.model_construct(name="grasp", args=("two words",)))
    with pytest.raises(InputError, match="MOVE"):
        format_statement(Move.model_construct(joints=(float("nan"),), speed=None, until=None))
    with pytest.raises(InputError, match="DRAW"):
        format_statement(Draw.model_construct(position=(float("inf"), 0.0, 0.0), frame=Frame.WORLD, speed=None, until=None))
