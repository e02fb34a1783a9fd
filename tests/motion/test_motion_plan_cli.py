"""``teleprog plan`` as a user runs it: the installed command in a subprocess."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shared.language.parser import parse_file
from shared.motion import plan_program
from shared.paths import ASSETS_DIR, PROJECT_DIR

TELEPROG = PROJECT_DIR / ".venv" / "bin" / "teleprog"
CELL = ASSETS_DIR / "cells" / "peg_in_hole.toml"
PEG_PROGRAM = ASSETS_DIR / "programs" / "peg_transfer.tp"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(TELEPROG), *args], capture_output=True, text=True, timeout=120)


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_plan_json_gives_durations_in_s_and_final_joints_in_deg(tmp_path: Path, cell) -> None:
    program = write(
        tmp_path, "p.tp",
        "SPEED 100 %\nMOVE (0, -40, 180, 0, 40, 0) deg\nDRAW TO (0, 0, 150) mm IN WORK\nEVENT done\nTASK grasp(peg)\n",
    )
    out = run("plan", str(program), "--robot", "puma562", "--cell", str(CELL), "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["ok"] is True and data["unit"] == "deg" and data["duration_unit"] == "s"
    kinds = [row["kind"] for row in data["statements"]]
    assert kinds == ["SPEED", "MOVE", "DRAW", "EVENT", "TASK"]
    durations = [row["duration"] for row in data["statements"]]
    assert durations[0] == 0.0 and durations[1] > 0 and durations[2] > 0 and durations[3] == 0.0 and durations[4] is None
    assert data["statements"][4]["task_end"] == "still" and "task_end" not in data["statements"][1]
    # the same numbers as the library computes in-process
    plan = plan_program(parse_file(program).statements, cell.robot, cell)
    np.testing.assert_allclose(data["final_q"], np.degrees(plan.q_final), atol=1e-5)
    assert math.isclose(data["total_duration"], plan.duration, abs_tol=1e-5)


def test_plan_of_the_peg_transfer_example_and_a_json_program(tmp_path: Path) -> None:
    out = run("plan", str(PEG_PROGRAM), "--robot", "puma562", "--cell", str(CELL), "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["total_duration"] > 0 and data["final_q_before_task"] == "insert_peg"
    program = write(tmp_path, "p.json", json.dumps([{"kind": "DRIVE", "joint": 1, "target": 0.5}]))
    out = run("plan", str(program), "--robot", "puma562", "--start", "0", "0", "0", "0", "0", "0", "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["final_q"] == pytest.approx([math.degrees(0.5), 0, 0, 0, 0, 0])
    text = run("plan", str(program), "--robot", "puma562")
    assert text.returncode == 0 and "DRIVE" in text.stdout and "deg" in text.stdout


def test_a_refused_statement_exits_1_with_the_reason(tmp_path: Path) -> None:
    program = write(tmp_path, "far.tp", "DRIVE J1 TO 10 deg\nDRAW TO (3000, 0, 0) mm\nDRIVE J1 TO 0 deg\n")
    out = run("plan", str(program), "--robot", "puma562", "--cell", str(CELL), "--json")
    assert out.returncode == 1
    data = json.loads(out.stdout)
    assert data["ok"] is False and len(data["statements"]) == 1
    assert data["refusal"]["index"] == 2 and data["refusal"]["reason"] == "unreachable"
    assert out.stderr.count("\n") == 1 and "statement 2" in out.stderr and "Traceback" not in out.stderr


@pytest.mark.parametrize(
    ("args", "code", "message"),
    [
        (["--robot", "puma562", "--start", "0", "0"], 1, "6 joints, got 2"),
        (["--robot", "puma562", "--start", "0", "90", "0", "0", "0", "0"], 1, "outside its range"),
        (["--robot", "nobot"], 1, "unknown robot"),
        ([], 2, "--robot"),
    ],
)
def test_bad_arguments_exit_1_or_2_without_traceback(tmp_path: Path, args: list[str], code: int, message: str) -> None:
    program = write(tmp_path, "p.tp", "DRIVE J1 TO 10 deg\n")
    out = run("plan", str(program), *args)
    assert out.returncode == code
    assert message in out.stderr and "Traceback" not in out.stderr


def test_bad_files_exit_1_with_every_error_located(tmp_path: Path) -> None:
    program = write(tmp_path, "bad.tp", "DRIVE J1 TO 10 deg\nMOVE (1, 2\nFLY AWAY\n")
    out = run("plan", str(program), "--robot", "puma562")
    assert out.returncode == 1 and "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 2 and "bad.tp:2:" in lines[0] and "bad.tp:3:" in lines[1]
    out = run("plan", str(write(tmp_path, "bad.json", "[{\"kind\": \"MOVE\"")), "--robot", "puma562")
    assert out.returncode == 1 and "not valid JSON" in out.stderr
    out = run("plan", str(tmp_path / "missing.tp"), "--robot", "puma562")
    assert out.returncode == 1 and "does not exist" in out.stderr
