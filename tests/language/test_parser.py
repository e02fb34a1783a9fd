"""The text parser: every kind, units to SI, case, comments, and located errors for bad lines."""

from __future__ import annotations

import json
import math

import pytest

from shared.errors import FileFormatError, InputError
from shared.language.parser import parse_file, parse_json, parse_program, parse_statement
from shared.language.statements import (
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
    SpeedUnit,
    TaskCall,
    UntilContact,
    UntilForce,
    UntilTime,
    program_to_json,
)


def one(text: str):
    result = parse_program(text)
    assert result.errors == [], result.error_lines()
    assert len(result.statements) == 1
    return result.statements[0]


def test_move_converts_degrees_to_radians() -> None:
    st = one("MOVE (0, -45.5, 1.2e2, 0, +30, 90) deg")
    assert isinstance(st, Move)
    assert st.joints == (0.0, math.radians(-45.5), math.radians(120), 0.0, math.radians(30), math.radians(90))
    assert st.speed is None and st.until is None


def test_drive_with_speed_percent() -> None:
    st = one("drive j3 to -30 DEG with speed 20 %")
    assert isinstance(st, Drive)
    assert (st.joint, st.target) == (3, math.radians(-30))
    assert st.speed is not None and st.speed.unit is SpeedUnit.FRACTION and st.speed.value == 0.2


def test_draw_mm_to_metres_frame_speed_until() -> None:
    st = one("DRAW TO (550, -80, 4.5e2) mm IN work WITH SPEED 20 mm/s UNTIL FORCE > 5 N")
    assert isinstance(st, Draw)
    assert st.position == (0.55, -0.08, 0.45)
    assert st.frame is Frame.WORK
    assert st.speed.unit is SpeedUnit.M_PER_S and st.speed.value == 0.02
    assert st.until == UntilForce(newtons=5.0)


def test_draw_default_frame_is_world_and_clauses_in_any_order() -> None:
    st = one("DRAW TO (1, 2, 3) mm UNTIL CONTACT WITH SPEED 5 % IN BASE")
    assert st.frame is Frame.BASE and st.until == UntilContact() and st.speed.value == 0.05
    assert one("DRAW TO (1, 2, 3) mm").frame is Frame.WORLD


def test_rotate_and_moves() -> None:
    st = one("ROTATE TO (180, 0, -90) deg IN TOOL UNTIL TIME 2.5 s")
    assert isinstance(st, Rotate)
    assert st.rpy == (math.pi, 0.0, math.radians(-90)) and st.until == UntilTime(seconds=2.5)
    st = one("MOVES TO (1, 2, 3) mm (4, 5, 6) deg WITH SPEED 10 deg/s")
    assert isinstance(st, Moves)
    assert st.position == (0.001, 0.002, 0.003)
    assert st.speed.unit is SpeedUnit.RAD_PER_S and st.speed.value == math.radians(10)


def test_parameter_and_task_statements() -> None:
    assert one("SPEED 50 %") == SetSpeed(speed={"value": 0.5, "unit": "fraction"})
    assert one("mode Force") == SetMode(mode=Mode.FORCE)
    assert one("MODE POSITION").mode is Mode.POSITION
    assert one("EVENT near_peg") == Event(name="near_peg")
    assert one("TASK insert_peg(PEG, HOLE1)") == TaskCall(name="insert_peg", args=("PEG", "HOLE1"))
    assert one("TASK release()") == TaskCall(name="release")
    assert one("task release") == TaskCall(name="release")


def test_comments_blank_lines_and_source_lines() -> None:
    text = "# header\n\nSPEED 10 %   # slow\n   \nEVENT a # note\n#MOVE (1) deg\nEVENT b"
    result = parse_program(text)
    assert result.ok
    assert [s.kind for s in result.statements] == ["SPEED", "EVENT", "EVENT"]
    assert result.lines == [3, 5, 7]


def test_number_forms() -> None:
    st = one("DRAW TO (-.5, +1., 2E-1) mm")
    assert st.position == (-0.0005, 0.001, 0.0002)


# (line text, column of the error, fragment of the message)
MALFORMED = [
    ("MOVE (1, 2) mm", 13, "expected deg"),
    ("MOVE 1, 2 deg", 6, "expected '('"),
    ("MOVE () deg", 7, "expected a number"),
    ("MOVE (1, 2 deg", 12, "expected ')' or ','"),
    ("MOVE (1, 2) deg extra", 17, "expected WITH or UNTIL"),
    ("MOVE (1, 2)", 12, "expected unit deg, found end of line"),
    ("MOVE (1;2) deg", 8, "unexpected character ';'"),
    ("DRIVE K3 TO 4 deg", 7, "a joint such as J3"),
    ("DRIVE J0 TO 4 deg", 7, "numbered from J1"),
    ("DRIVE J3 4 deg", 10, "expected TO"),
    ("DRIVE J3 TO deg", 13, "expected a number"),
    ("DRAW TO (1, 2) mm", 9, "expected 3 values"),
    ("DRAW TO (1, 2, 3, 4) mm", 9, "expected 3 values"),
    ("DRAW (1, 2, 3) mm", 6, "expected TO"),
    ("DRAW TO (1, 2, 3) deg", 19, "expected mm"),
    ("DRAW TO (1, 2, 3) mm IN SPACE", 25, "a frame"),
    ("ROTATE TO (1, 2, 3) mm", 21, "expected deg"),
    ("MOVES TO (1, 2, 3) mm deg", 23, "expected '('"),
    ("MOVES TO (1, 2, 3) mm (1, 2, 3) deg WITH SPEED 3 % WITH SPEED 4 %", 52, "WITH given twice"),
    ("MOVE (1, 2) deg IN WORK", 17, "IN applies to DRAW"),
    ("DRAW TO (1, 2, 3) mm UNTIL FORCE 5 N", 34, "expected '>'"),
    ("DRAW TO (1, 2, 3) mm UNTIL FORCE > 5 kg", 38, "unit N"),
    ("DRAW TO (1, 2, 3) mm UNTIL FORCE > 0 N", 36, "above zero"),
    ("DRAW TO (1, 2, 3) mm UNTIL TIME 2 mm", 35, "does not fit here"),
    ("DRAW TO (1, 2, 3) mm UNTIL SOON", 28, "FORCE, CONTACT or TIME"),
    ("DRAW TO (1, 2, 3) mm WITH 3 %", 27, "SPEED after WITH"),
    ("DRAW TO (1, 2, 3) mm WITH SPEED 3 N", 35, "does not fit here"),
    ("SPEED 0 %", 7, "above zero"),
    ("SPEED -5 %", 7, "above zero"),
    ("SPEED 1e999 mm/s", 7, "too large"),
    ("SPEED fast", 7, "expected a speed"),
    ("SPEED 5", 8, "end of line"),
    ("MODE fast", 6, "FORCE or POSITION"),
    ("EVENT 3x", 7, "event name"),
    ("EVENT", 6, "event name"),
    ("EVENT a b", 9, "unexpected 'b'"),
    ("TASK a(b,", 10, "object or feature name"),
    ("TASK a(b c)", 10, "expected ')' or ','"),
    ("TASK (b)", 6, "task name"),
    ("FOO bar", 1, "unknown statement 'FOO'"),
    ("42", 1, "expected a statement"),
    ("   MOVE [1] deg", 9, "unexpected character '['"),
    ("DRAW TO (1, 2, 3) mm \u00e9", 22, "unexpected character"),
    ("DRAW TO (1, nan, 3) mm", 13, "expected a number"),
]


@pytest.mark.parametrize(("line", "col", "fragment"), MALFORMED)
def test_malformed_line_is_located(line: str, col: int, fragment: str) -> None:
    result = parse_program("EVENT ok\n" + line + "\n")
    assert len(result.errors) == 1, result.error_lines()
    err = result.errors[0]
    assert (err.line, err.col) == (2, col), err
    assert fragment in err.message
    assert err.format("p.tp").startswith(f"p.tp:2:{col}: ")
    assert [s.kind for s in result.statements] == ["EVENT"]


def test_every_error_in_a_file_is_reported() -> None:
    lines = [line for line, _, _ in MALFORMED]
    text = "\n".join(x for pair in zip(["EVENT good"] * len(lines), lines) for x in pair)
    result = parse_program(text, "many.tp")
    assert [e.line for e in result.errors] == [2 * i + 2 for i in range(len(lines))]
    assert [e.col for e in result.errors] == [c for _, c, _ in MALFORMED]
    assert len(result.statements) == len(lines)
    assert result.error_lines()[0].startswith("many.tp:2:")


def test_parse_statement_single_line() -> None:
    assert parse_statement("SPEED 5 %").kind == "SPEED"
    with pytest.raises(InputError, match="column 6"):
        parse_statement("MODE fast")
    with pytest.raises(InputError):
        parse_statement("# nothing")
    with pytest.raises(InputError):
        parse_statement("EVENT a\nEVENT b")


def test_json_form_input_and_its_errors() -> None:
    good = program_to_json(parse_program("SPEED 5 %\nDRAW TO (1, 2, 3) mm IN WORK").statements)
    result = parse_json(json.dumps(good))
    assert result.ok and program_to_json(result.statements) == good
    assert result.lines == [None, None]
    bad = parse_json(json.dumps([good[0], {"kind": "MOVE", "joints": []}, {"kind": "JUMP"}]), "p.json")
    assert [e.statement for e in bad.errors] == [1, 2]
    assert bad.error_lines()[0].startswith("p.json: /1/joints: ")
    assert bad.error_lines()[1].startswith("p.json: /2/kind: ")
    syntax = parse_json('[{"kind": "EVENT",\n "name": }]', "s.json")
    assert (syntax.errors[0].line, syntax.errors[0].col) == (2, 10)
    assert syntax.error_lines()[0].startswith("s.json:2:10: not valid JSON")
    assert not parse_json('{"kind": "EVENT"}').ok
    # the text form has finite numbers only, so the JSON form may not smuggle in others
    nan = parse_json('[{"kind": "EVENT", "name": "a"}, {"kind": "DRIVE", "joint": 1, "target": NaN}]', "n.json")
    assert nan.error_lines() == ["n.json: /1/target: NaN is not a JSON number (only finite numbers are accepted)"]
    assert "too large" in parse_json('[{"kind": "DRIVE", "joint": 1, "target": -1e999}]').errors[0].message


def test_parse_file_errors(tmp_path) -> None:
    with pytest.raises(FileFormatError, match="does not exist"):
        parse_file(tmp_path / "missing.tp")
    binary = tmp_path / "b.tp"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(FileFormatError, match="UTF-8"):
        parse_file(binary)
    p = tmp_path / "p.json"
    p.write_text('[{"kind": "EVENT", "name": "x"}]')
    assert parse_file(p).statements == [Event(name="x")]


def test_huge_tokens_are_clipped_in_messages() -> None:
    result = parse_program("MOVE (" + "9" * 5000 + ") deg\nEVENT " + "x" * 3000 + " y")
    assert [e.line for e in result.errors] == [1, 2]
    assert all(len(e.message) < 200 for e in result.errors)
    assert "(5000 characters)" in result.errors[0].message


def test_windows_line_endings_and_tabs() -> None:
    result = parse_program("SPEED 10 %\r\n\tMODE\tforce\r\nMODE x\r\n")
    assert [s.kind for s in result.statements] == ["SPEED", "MODE"]
    assert [(e.line, e.col) for e in result.errors] == [(3, 6)]


@pytest.mark.timeout(60)
def test_pathological_inputs_finish() -> None:
    # megabyte-sized lines of the kinds that make backtracking parsers hang
    for text in ("(" * 300_000, "MOVE (" + "1," * 50_000 + ") deg", "9" * 1_000_000, "e" * 1_000_000,
                 "MOVE (" + "1e" * 50_000 + ") deg", "#" * 1_000_000 + "\n" * 100_000 + "EVENT x"):
        result = parse_program(text)
        assert result.statements or result.errors
