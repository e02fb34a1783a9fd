"""``teleprog parse`` and ``teleprog check`` as a user runs them: real subprocesses, exit codes."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TELEPROG = ROOT / ".venv" / "bin" / "teleprog"
PEG = ROOT / "assets" / "programs" / "peg_transfer.tp"
ROVER = ROOT / "assets" / "programs" / "rover_placement.tp"
PEG_CELL = ROOT / "assets" / "cells" / "peg_in_hole.toml"


def tp(*args: str | Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(TELEPROG), *map(str, args)], capture_output=True, text=True, timeout=120, cwd=ROOT)


def test_parse_prints_json_and_text_round_trips(tmp_path: Path) -> None:
    out = tp("parse", PEG)
    assert out.returncode == 0, out.stderr
    program = json.loads(out.stdout)
    assert [s["kind"] for s in program][:3] == ["SPEED", "MOVES", "EVENT"]
    assert program[1]["position"] == [0.0, -0.08, 0.16] and program[1]["frame"] == "WORK"
    one_line = tp("parse", PEG, "--json")
    assert one_line.returncode == 0 and json.loads(one_line.stdout) == program
    text = tp("parse", PEG, "--text")
    assert text.returncode == 0
    assert "MOVES TO (0, -80, 160) mm (180, 0, 0) deg IN WORK" in text.stdout
    # text -> JSON -> text -> JSON through the command line, and .json input
    again = tmp_path / "again.tp"
    again.write_text(text.stdout)
    assert json.loads(tp("parse", again).stdout) == program
    as_json = tmp_path / "p.json"
    as_json.write_text(out.stdout)
    assert tp("parse", as_json, "--text").stdout == text.stdout


def test_parse_reports_every_error_with_line_and_column(tmp_path: Path) -> None:
    bad = tmp_path / "bad.tp"
    bad.write_text("SPEED 10 %\nMOVE (1, 2 deg\nEVENT ok\nMODE fast\nDRAW TO (1, 2) mm\n")
    out = tp("parse", bad)
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert lines[:3] == [
        f"{bad}:2:12: expected ')' or ',', found 'deg'",
        f"{bad}:4:6: expected FORCE or POSITION, found 'fast'",
        f"{bad}:5:9: expected 3 values in parentheses, found 2",
    ]
    assert "Traceback" not in out.stderr and out.stdout == ""


def test_parse_usage_and_file_errors(tmp_path: Path) -> None:
    assert tp("parse").returncode == 2
    assert tp("parse", PEG, "--bogus").returncode == 2
    missing = tp("parse", tmp_path / "none.tp")
    assert missing.returncode == 1 and "does not exist" in missing.stderr and "Traceback" not in missing.stderr
    broken = tmp_path / "b.json"
    broken.write_text('[{"kind": "MOVE", "joints": "x"}]')
    out = tp("parse", broken)
    assert out.returncode == 1 and "b.json: /0/joints: " in out.stderr


def test_check_example_is_clean() -> None:
    out = tp("check", PEG, "--robot", "puma562", "--cell", PEG_CELL)
    assert out.returncode == 0, out.stdout + out.stderr
    assert out.stdout.strip().endswith("ok, 14 statements")
    js = tp("check", PEG, "--robot", "puma562", "--cell", PEG_CELL, "--json")
    report = json.loads(js.stdout)
    assert js.returncode == 0 and report["ok"] and report["problems"] == [] and report["unit"] == "deg"


def test_check_prints_one_line_per_problem(tmp_path: Path) -> None:
    prog = tmp_path / "p.tp"
    prog.write_text("MOVE (1, 2, 3) deg\n# fine\n  DRIVE J2 TO 80 deg\nTASK fly(peg)\nDRIVE J1 TO 0 deg\nMODE odd\n")
    out = tp("check", prog, "--robot", "puma562", "--cell", PEG_CELL)
    assert out.returncode == 1
    lines = out.stdout.strip().splitlines()
    assert lines[-1] == f"{prog}:6:6: expected FORCE or POSITION, found 'odd'"
    # every problem as file:line:col, as the README promises (the column of the statement)
    assert [line.split(": ")[0] for line in lines[:-1]] == [f"{prog}:1:1", f"{prog}:3:3", f"{prog}:4:1", f"{prog}:5:1"]
    js = json.loads(tp("check", prog, "--robot", "puma562", "--cell", PEG_CELL, "--json").stdout)
    assert [p["rule"] for p in js["problems"]] == ["joints", "limits", "names", "program"]
    assert js["parse_errors"][0]["line"] == 6


def test_check_start_vector_and_usage_errors() -> None:
    ok = tp("check", PEG, "--robot", "puma562", "--cell", PEG_CELL, "--start", "-15.18", "-45.52", "196.42", "0", "29.1", "164.82")
    assert ok.returncode == 0, ok.stdout + ok.stderr
    wrong = tp("check", PEG, "--robot", "puma562", "--cell", PEG_CELL, "--start", "1", "2")
    assert wrong.returncode == 1 and "--start needs 6 joint angles" in wrong.stderr
    outside = tp("check", PEG, "--robot", "puma562", "--start", "0", "0", "0", "0", "150", "0")
    assert outside.returncode == 1 and "outside its range" in outside.stderr
    assert tp("check", PEG).returncode == 2  # --robot is required
    assert tp("check", PEG, "--robot", "nosuch").returncode == 1
    assert tp("check", PEG, "--robot", "puma562", "--start", "x").returncode == 2


def test_rover_example_checks_clean() -> None:
    out = tp("check", ROVER, "--robot", "rover", "--cell", ROOT / "assets" / "cells" / "rover_empty.toml")
    assert out.returncode == 0, out.stdout + out.stderr
