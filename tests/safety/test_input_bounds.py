"""Finite, bounded input wherever a statement or a file enters as data (issue 14, findings 1, 8,
10, 11): the text form, the JSON form, a wire unit, cell and robot files, the command line.

Each bad number (NaN, infinity, 1e308, a value past a physical bound) is refused at every door
with one message naming the field; fuzzed unit bodies and statement JSON never raise and never
let an unbounded number through; bad cell files and endless program streams end the real
``teleprog`` command with exit 1 and one line.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shared.language import bounds
from shared.language.parser import parse_json, parse_program
from shared.language.statements import SPEED_BOUND
from shared.wire.messages import Rejected, RejectReason
from shared.wire.units import HEADER, MAGIC, UNIT_VERSION, CommandUnit, decode_unit

ROOT = Path(__file__).resolve().parents[2]
PEG_CELL = ROOT / "assets" / "cells" / "peg_in_hole.toml"
PEG = ROOT / "assets" / "programs" / "peg_transfer.tp"


def teleprog(*args: object, timeout: float = 60, **kwargs) -> subprocess.CompletedProcess:
    """The real command line, as a subprocess of this checkout's code."""
    return subprocess.run(
        [sys.executable, "-m", "server.cli", *map(str, args)], capture_output=True, text=True, timeout=timeout,
        cwd=ROOT, **kwargs,
    )


def one_error_line(out: subprocess.CompletedProcess) -> str:
    """The single line a refused command prints on stderr (no traceback)."""
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 1, (out.returncode, out.stderr)
    assert len(lines) == 1 and "Traceback" not in out.stderr, out.stderr
    return lines[0]


def unit(body: bytes, comm_id: int = 1, seq: int = 0) -> bytes:
    return HEADER.pack(MAGIC, UNIT_VERSION, 1, comm_id, seq, len(body)) + body


# -- each bad number through the three doors --------------------------------------------------

# (JSON statement with the bad value spliced in as raw JSON text, field pointer, text form or None)
BAD_NUMBERS = [
    ('{"kind":"DRIVE","joint":1,"target":NaN}', "/0/target", None),
    ('{"kind":"DRIVE","joint":1,"target":Infinity}', "/0/target", None),
    ('{"kind":"DRIVE","joint":1,"target":1e999}', "/0/target", "DRIVE J1 TO 1e999 deg"),
    ('{"kind":"DRIVE","joint":1,"target":1e308}', "/0/target", "DRIVE J1 TO 1e308 deg"),
    ('{"kind":"DRAW","position":[1e308,0,0]}', "/0/position/0", "DRAW TO (1e308, 0, 0) mm"),
    ('{"kind":"DRAW","position":[0,-101,0]}', "/0/position/1", "DRAW TO (0, -101000, 0) mm"),
    ('{"kind":"MOVES","position":[0,0,0],"rpy":[0,NaN,0]}', "/0/rpy/1", None),
    ('{"kind":"MOVES","position":[0,0,0],"rpy":[0,0,1e308]}', "/0/rpy/2", "MOVES TO (0, 0, 0) mm (0, 0, 1e308) deg"),
    ('{"kind":"MOVE","joints":[0,0,-Infinity]}', "/0/joints/2", None),
    ('{"kind":"MOVE","joints":[0,0,13]}', "/0/joints/2", "MOVE (0, 0, 745) deg"),
    ('{"kind":"SPEED","speed":{"value":11,"unit":"m/s"}}', "/0/speed", "SPEED 11000 mm/s"),
    ('{"kind":"SPEED","speed":{"value":NaN,"unit":"fraction"}}', "/0/speed/value", None),
    ('{"kind":"DRAW","position":[0,0,0],"speed":{"value":1e308,"unit":"fraction"}}', "/0/speed", "DRAW TO (0, 0, 0) mm WITH SPEED 1e308 %"),
    ('{"kind":"MOVE","joints":[0],"until":{"kind":"force","newtons":1e308}}', "/0/until/newtons", "MOVE (0) deg UNTIL FORCE > 1e308 N"),
    ('{"kind":"MOVE","joints":[0],"until":{"kind":"time","seconds":1e5}}', "/0/until/seconds", "MOVE (0) deg UNTIL TIME 100000 s"),
    ('{"kind":"MOVE","joints":[0],"until":{"kind":"time","seconds":Infinity}}', "/0/until/seconds", None),
]


@pytest.mark.parametrize(("statement", "where", "text"), BAD_NUMBERS)
def test_a_bad_number_is_refused_by_the_json_form_with_its_pointer(statement: str, where: str, text: str | None) -> None:
    parsed = parse_json(f"[{statement}]", "p.json")
    assert not parsed.statements
    assert [e.pointer for e in parsed.errors] == [where], parsed.error_lines()
    assert parsed.error_lines()[0].startswith(f"p.json: {where}: ")


@pytest.mark.parametrize(("statement", "where", "text"), BAD_NUMBERS)
def test_a_bad_number_is_refused_by_a_wire_unit_naming_index_and_field(statement: str, where: str, text: str | None) -> None:
    good = '{"kind":"EVENT","name":"before"}'
    answer = decode_unit(unit(f"[{good},{statement}]".encode()))
    assert isinstance(answer, Rejected), answer
    assert answer.reason in (RejectReason.BAD_JSON, RejectReason.INVALID_STATEMENT)
    assert answer.statement_index == 1
    assert "/1/" + where.split("/", 2)[2] in answer.detail, answer.detail


@pytest.mark.parametrize(("statement", "where", "text"), [b for b in BAD_NUMBERS if b[2] is not None])
def test_a_bad_number_is_refused_by_the_text_form_at_its_column(statement: str, where: str, text: str) -> None:
    parsed = parse_program(f"EVENT before\n{text}\n", "p.tp")
    assert not [s for s in parsed.statements if s.kind != "EVENT"]
    (error,) = parsed.errors
    assert error.line == 2
    bad_token = next(t for t in ("1e999", "1e308", "-101000", "745", "11000", "100000") if t in text)
    assert error.col == text.index(bad_token) + 1, (error, text)
    assert ("too large" in error.message) or ("beyond the" in error.message), error.message


def test_the_text_form_names_the_field_and_the_bound() -> None:
    (error,) = parse_program("DRAW TO (0, 1e308, 0) mm").errors
    assert error.message == "y = 1e308 mm is beyond the workspace bound of \u00b1100000 mm"
    (error,) = parse_program("DRIVE J2 TO 1000 deg").errors
    assert error.message == "J2 = 1000 deg is beyond the angle bound of \u00b1720 deg"


def test_a_repeated_key_cannot_turn_one_statement_into_another() -> None:
    body = b'[{"kind":"EVENT","name":"a","kind":"DRIVE","joint":1,"target":1}]'
    answer = decode_unit(unit(body))
    assert isinstance(answer, Rejected) and answer.reason is RejectReason.BAD_JSON
    assert answer.statement_index == 0 and "/0/kind" in answer.detail and "twice" in answer.detail
    parsed = parse_json(body.decode(), "p.json")
    assert parsed.error_lines() == ["p.json: /0/kind: key 'kind' appears twice in one object"]


@pytest.mark.parametrize("form", ["text", "json", "wire"])
def test_names_and_task_arguments_are_bounded(form: str) -> None:
    long_name = "e" * (bounds.MAX_NAME_LENGTH + 1)
    many_args = ", ".join(f"a{i}" for i in range(bounds.MAX_TASK_ARGS + 1))
    cases = [(f"EVENT {long_name}", {"kind": "EVENT", "name": long_name}),
             (f"TASK grasp({many_args})", {"kind": "TASK", "name": "grasp", "args": many_args.split(", ")}),
             (f"TASK {long_name}()", {"kind": "TASK", "name": long_name})]
    for text, document in cases:
        if form == "text":
            (error,) = parse_program(text).errors
            assert str(bounds.MAX_NAME_LENGTH) in error.message or str(bounds.MAX_TASK_ARGS) in error.message
        elif form == "json":
            parsed = parse_json(json.dumps([document]))
            assert not parsed.statements and parsed.errors[0].pointer.startswith("/0/")
        else:
            answer = decode_unit(unit(json.dumps([document]).encode()))
            assert isinstance(answer, Rejected) and answer.reason is RejectReason.INVALID_STATEMENT


def test_a_program_is_bounded_in_statements(monkeypatch) -> None:
    monkeypatch.setattr(bounds, "MAX_PROGRAM_STATEMENTS", 3)
    text = parse_program("EVENT a\nEVENT b\n# c\nEVENT c\nEVENT d\nEVENT e\n", "p.tp")
    assert len(text.statements) == 3
    assert text.error_lines() == ["p.tp:5:1: more than 3 statements in one program"]
    parsed = parse_json(json.dumps([{"kind": "EVENT", "name": "x"}] * 4))
    assert not parsed.statements and "more than the 3" in parsed.errors[0].message


def test_the_legitimate_extremes_still_parse() -> None:
    """The bounds refuse garbage only: the edges of every bound are statements."""
    text = (
        "DRAW TO (100000, -100000, 0) mm IN WORK\nMOVE (720, -720) deg\nSPEED 1000 %\n"
        "DRIVE J32 TO 0 deg WITH SPEED 10000 mm/s UNTIL FORCE > 10000 N\nROTATE TO (0, 0, 1) deg UNTIL TIME 3600 s\n"
        f"EVENT {'e' * bounds.MAX_NAME_LENGTH}\n"
    )
    parsed = parse_program(text)
    assert parsed.ok, parsed.error_lines()
    for path in sorted((ROOT / "assets" / "programs").glob("*.tp")):
        assert parse_program(path.read_text()).ok, path


# -- fuzzing: nothing raises, nothing unbounded gets through ----------------------------------

_NUMBER_TEXT = st.one_of(
    st.sampled_from(["NaN", "Infinity", "-Infinity", "1e308", "-1e308", "1e999", "0", "-0.0", "1e-320", "13", "101",
                     "3601", "99999999999999999999", "1" + "0" * 400]),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.integers(-(10**30), 10**30).map(str),
)
_KINDS = ["MOVE", "DRIVE", "DRAW", "ROTATE", "MOVES", "SPEED", "MODE", "EVENT", "TASK", "JUMP"]


@st.composite
def statement_json(draw: st.DrawFn) -> str:
    """A statement object as JSON text with hostile numbers and keys (raw text, so NaN,
    Infinity, overflowing numbers and repeated keys can be spelled)."""
    n = _NUMBER_TEXT
    kind = draw(st.sampled_from(_KINDS))
    fields = [f'"kind":"{kind}"']
    options = {
        "joints": lambda: "[" + ",".join(draw(st.lists(n, min_size=0, max_size=7))) + "]",
        "joint": lambda: draw(n),
        "target": lambda: draw(n),
        "position": lambda: "[" + ",".join(draw(st.lists(n, min_size=2, max_size=4))) + "]",
        "rpy": lambda: "[" + ",".join(draw(st.lists(n, min_size=3, max_size=3))) + "]",
        "speed": lambda: '{"value":%s,"unit":"%s"}' % (draw(n), draw(st.sampled_from(["fraction", "m/s", "rad/s", "x"]))),
        "until": lambda: draw(st.sampled_from(['{"kind":"force","newtons":%s}', '{"kind":"time","seconds":%s}'])) % draw(n),
        "name": lambda: json.dumps(draw(st.text(min_size=0, max_size=80))),
        "args": lambda: json.dumps(draw(st.lists(st.text(max_size=70), max_size=10))),
        "mode": lambda: draw(st.sampled_from(['"FORCE"', '"POSITION"', "1"])),
        "frame": lambda: draw(st.sampled_from(['"WORK"', '"TOOL"', '"MARS"'])),
        "kind": lambda: '"EVENT"',  # a repeated key
    }
    for key in draw(st.lists(st.sampled_from(sorted(options)), max_size=5)):
        fields.append(f'"{key}":{options[key]()}')
    return "{" + ",".join(fields) + "}"


def _assert_bounded(statement) -> None:
    """Every number of an accepted statement is finite and within its physical bound."""
    data = statement.model_dump()
    for key in ("joints", "position", "rpy", "target"):
        values = data.get(key)
        if values is None:
            continue
        values = values if isinstance(values, (list, tuple)) else [values]
        limit = bounds.WORKSPACE_M if key == "position" else bounds.MAX_ANGLE_RAD
        assert all(math.isfinite(v) and abs(v) <= limit for v in values), data
    speed = data.get("speed")
    if speed is not None:
        assert math.isfinite(speed["value"]) and 0 < speed["value"] <= SPEED_BOUND[speed["unit"]], data
    until = data.get("until") or {}
    if "newtons" in until:
        assert math.isfinite(until["newtons"]) and 0 < until["newtons"] <= bounds.MAX_FORCE_N
    if "seconds" in until:
        assert math.isfinite(until["seconds"]) and 0 < until["seconds"] <= bounds.MAX_TIME_S
    for name in [data.get("name")] + list(data.get("args") or []):
        assert name is None or len(name) <= bounds.MAX_NAME_LENGTH


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(statement_json(), max_size=4))
def test_fuzzed_unit_bodies_never_raise_and_admit_only_bounded_numbers(items: list[str]) -> None:
    answer = decode_unit(unit(("[" + ",".join(items) + "]").encode()))
    assert isinstance(answer, (CommandUnit, Rejected))
    if isinstance(answer, Rejected):
        assert answer.detail and "\n" not in answer.detail
        if answer.statement_index is not None:
            assert 0 <= answer.statement_index < len(items)
    else:
        for statement in answer.statements:
            _assert_bounded(statement)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(statement_json(), max_size=4))
def test_fuzzed_statement_json_never_raises_and_admits_only_bounded_numbers(items: list[str]) -> None:
    parsed = parse_json("[" + ",".join(items) + "]", "f.json")
    for statement in parsed.statements:
        _assert_bounded(statement)
    for line in parsed.error_lines():
        assert line.startswith("f.json") and "\n" not in line and "statement " not in line


# -- files and the command line ---------------------------------------------------------------

BAD_CELLS = [
    ("xyz = [0.0, 0.0, 660.0]", "xyz = [inf, 0.0, 660.0]", "robot.xyz[0]"),
    ("tcp = { xyz = [0.0, 0.0, 110.0] }", "tcp = { xyz = [0.0, nan, 110.0] }", "robot.tcp.xyz[1]"),
    ("rpy = [0.0, 0.0, 0.0]", "rpy = [1e308, 0.0, 0.0]", "robot.rpy[0]"),
    ("size = [20.0, 20.0, 80.0]", "size = [20.0, 20.0, 0.0]", "objects[2].shapes[0].size[2]"),
    ("size = [20.0, 20.0, 80.0]", "size = [-20.0, 20.0, 80.0]", "objects[2].shapes[0].size[0]"),
    ("color = [200, 160, 40]", "color = [999, -1, 0]", "objects[2].color[0]"),
    ('kind = "hole"', 'kind = "wormhole"', "features[0].kind"),
]


@pytest.mark.parametrize(("old", "new", "field"), BAD_CELLS)
def test_a_bad_cell_file_ends_the_command_with_one_line_naming_file_and_field(tmp_path, old, new, field) -> None:
    text = PEG_CELL.read_text()
    assert old in text
    cell = tmp_path / "cell.toml"
    cell.write_text(text.replace(old, new, 1))
    line = one_error_line(teleprog("check", PEG, "--robot", "puma562", "--cell", cell))
    assert line.startswith(f"teleprog: error: {cell}: {field}: "), line


def test_the_robot_refuses_a_bad_cell_with_the_same_line(tmp_path) -> None:
    cell = tmp_path / "cell.toml"
    cell.write_text(PEG_CELL.read_text().replace("xyz = [0.0, 0.0, 660.0]", "xyz = [inf, 0.0, 660.0]", 1))
    line = one_error_line(teleprog("robot", "--port", "0", "--cell", cell))
    assert line == f"teleprog: error: {cell}: robot.xyz[0]: Input should be a finite number"


def test_a_mesh_folder_is_named_as_a_folder(tmp_path) -> None:
    (tmp_path / "peg.stl").mkdir()
    cell = tmp_path / "cell.toml"
    cell.write_text(PEG_CELL.read_text().replace('shape = "box", size = [20.0, 20.0, 80.0]', 'shape = "mesh", mesh = "peg.stl"'))
    line = one_error_line(teleprog("check", PEG, "--robot", "puma562", "--cell", cell))
    assert "objects[2].shapes[0].mesh: " in line and "is a folder, not a mesh file" in line


def test_parse_of_an_endless_device_stops_at_the_bound() -> None:
    out = teleprog("parse", "/dev/zero", timeout=60)
    assert one_error_line(out) == "teleprog: error: /dev/zero: larger than 8 MiB, the bound of a program file; stopped reading there"


def test_parse_of_an_endless_pipe_stops_at_the_bound(tmp_path) -> None:
    fifo = tmp_path / "endless.tp"
    os.mkfifo(fifo)
    stop = threading.Event()

    def write_forever() -> None:
        line = b"EVENT again\n" * 4096
        try:
            with open(fifo, "wb") as f:
                while not stop.is_set():
                    f.write(line)
        except (BrokenPipeError, OSError):
            pass  # the reader stopped reading: what this test wants

    writer = threading.Thread(target=write_forever, daemon=True)
    writer.start()
    try:
        out = teleprog("parse", fifo, timeout=60)
    finally:
        stop.set()
    assert "larger than 8 MiB" in one_error_line(out)
    writer.join(timeout=10)


def test_check_prints_every_problem_as_file_line_col(tmp_path) -> None:
    program = tmp_path / "p.tp"
    program.write_text("EVENT start\n    DRIVE J2 TO 80 deg\nDRAW TO (0, 1e308, 0) mm\n  MODE sideways\n")
    out = teleprog("check", program, "--robot", "puma562")
    assert out.returncode == 1
    assert out.stdout.splitlines() == [
        f"{program}:2:5: DRIVE J2: joint 2 at 80.000 deg is outside its range [-205.000, 45.000] deg",
        f"{program}:3:13: y = 1e308 mm is beyond the workspace bound of \u00b1100000 mm",
        f"{program}:4:8: expected FORCE or POSITION, found 'sideways'",
    ]


def test_check_of_a_json_program_points_into_the_document(tmp_path) -> None:
    program = tmp_path / "p.json"
    program.write_text('[{"kind": "EVENT", "name": "a"}, {"kind": "DRIVE", "joint": 2, "target": 1.4},\n'
                       ' {"kind": "DRAW", "position": [0, 0, NaN]}]')
    out = teleprog("check", program, "--robot", "puma562")
    assert out.returncode == 1
    assert out.stdout.splitlines() == [f"{program}: /2/position/2: NaN is not a JSON number (only finite numbers are accepted)"]
    program.write_text('[{"kind": "EVENT", "name": "a"}, {"kind": "DRIVE", "joint": 2, "target": 1.4}]')
    out = teleprog("check", program, "--robot", "puma562")
    assert out.stdout.splitlines() == [
        f"{program}: /1/target: DRIVE J2: joint 2 at 80.214 deg is outside its range [-205.000, 45.000] deg"
    ]


def test_parse_and_plan_of_a_json_program_with_nan_give_the_pointer(tmp_path) -> None:
    program = tmp_path / "p.json"
    program.write_text('[{"kind":"DRIVE","joint":1,"target":NaN}]')
    for command in ("parse", "plan"):
        extra = ("--robot", "puma562") if command == "plan" else ()
        out = teleprog(command, program, *extra)
        assert out.returncode == 1 and "Traceback" not in out.stderr
        assert f"{program}: /0/target: NaN is not a JSON number" in out.stderr, out.stderr
