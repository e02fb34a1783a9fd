"""The lunar-rover arm of seed 004: fitted DH reproduces Table 2, closed-form IK, CLI, limits."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.errors import JointLimitError
from shared.robots.ik import solve_ik
from shared.robots.ik_rover import rover_ik_all
from shared.robots.loader import ROBOTS_DIR, load_robot
from tests.support import PROJECT_DIR

ROVER_DIR = ROBOTS_DIR / "rover"
TELEPROG = PROJECT_DIR / ".venv" / "bin" / "teleprog"

# Seed 004, Table 2: joint angles (deg) -> point C (m) in the table's frame, and how many IK
# solutions the paper found within the joint ranges.
TABLE2 = [
    ((0, 0, 0), (0.548, 0.038, -0.146), 1),
    ((-5, -5, -5), (0.559, 0.027, -0.154), 1),
    ((-10, -10, -10), (0.572, 0.013, -0.158), 1),
    ((-20, -20, -20), (0.608, -0.017, -0.156), 1),
    ((-30, -30, -30), (0.658, -0.041, -0.136), 1),
    ((-30, -30, -60), (0.714, -0.138, -0.131), 1),
    ((-30, -30, -120), (0.787, -0.264, 0.028), 2),
    ((-30, -30, -190), (0.740, -0.182, 0.257), 2),
    ((-40, -30, -190), (0.793, -0.141, 0.257), 2),
    ((-40, -40, -190), (0.751, -0.092, 0.319), 2),
    ((-40, -70, -220), (0.529, 0.173, 0.384), 1),
]
ROW_IDS = [f"row{i}" for i in range(1, len(TABLE2) + 1)]


def table2_p_base() -> np.ndarray:
    """Origin of the robot's base frame in Table 2's frame (m), as recorded by the fit (zero if
    the robot file ever carries the mount in its kinematics instead)."""
    raw = tomllib.loads((ROVER_DIR / "robot.toml").read_text(encoding="utf-8"))
    return np.array(raw.get("fit", {}).get("table2_p_base", [0.0, 0.0, 0.0]), dtype=float) * 1e-3


def base_p(row_xyz: tuple[float, float, float]) -> np.ndarray:
    """A Table 2 position expressed in the robot's base frame (m)."""
    return np.array(row_xyz) - table2_p_base()


def teleprog(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(TELEPROG), *args], capture_output=True, text=True, timeout=120)


def angle_gap_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Largest per-joint difference modulo 360 deg."""
    d = (np.asarray(a, dtype=float) - np.asarray(b, dtype=float) + 180.0) % 360.0 - 180.0
    return float(np.max(np.abs(d)))


@pytest.fixture(scope="module")
def rover():
    return load_robot("rover")


def test_adopted_joint_ranges(rover) -> None:
    assert rover.dof == 3
    np.testing.assert_allclose(np.degrees(rover.lower), [-70, -70, -270])
    np.testing.assert_allclose(np.degrees(rover.upper), [0, 10, 0])


@pytest.mark.parametrize(("q_deg", "xyz", "count"), TABLE2, ids=ROW_IDS)
def test_fk_reproduces_table2_within_1mm(rover, q_deg, xyz, count) -> None:
    base_T_tool = rover.fk(np.radians(q_deg))
    error = np.linalg.norm(base_T_tool[:3, 3] - base_p(xyz))
    assert error < 1e-3, f"{q_deg}: {error * 1e3:.3f} mm"


@pytest.mark.parametrize(("q_deg", "xyz", "count"), TABLE2, ids=ROW_IDS)
def test_solution_count_within_ranges_matches_table2(rover, q_deg, xyz, count) -> None:
    """The adopted ranges give exactly the paper's number of solutions per row."""
    target = rover.fk(np.radians(q_deg))[:3, 3]
    solutions = solve_ik(rover, position=target, q_near=np.radians(q_deg))
    assert len(solutions) == count
    assert angle_gap_deg(np.degrees(solutions[0]), q_deg) < 1e-6


def test_fit_script_runs_and_every_row_is_within_1mm() -> None:
    out = subprocess.run(
        [sys.executable, str(ROVER_DIR / "fit_dh.py")], capture_output=True, text=True, timeout=120, cwd=PROJECT_DIR
    )
    assert out.returncode == 0, out.stdout + out.stderr
    assert out.stdout.count("| ") >= 2 * len(TABLE2)
    assert "robot.toml" in out.stdout


@pytest.mark.parametrize("row", [6, 10])
def test_cli_fk_prints_point_c_in_metres(row: int) -> None:
    q_deg, xyz, _ = TABLE2[row]
    out = teleprog("kin", "fk", "--robot", "rover", "--deg", *map(str, q_deg), "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["unit"] == "m"
    assert np.linalg.norm(np.array(data["position"]) - base_p(xyz)) < 1e-3


@pytest.mark.parametrize(("q_deg", "xyz", "count"), TABLE2, ids=ROW_IDS)
def test_cli_ik_ignoring_limits_finds_the_row(q_deg, xyz, count) -> None:
    """Table 2 prints C to 1 mm; near joint 1's axis (row 11) that is worth up to ~0.7 deg."""
    target = base_p(xyz)
    out = teleprog("kin", "ik", "--robot", "rover", "--xyz", *map(str, target), "--ignore-limits", "--json")
    assert out.returncode == 0, out.stderr
    solutions = json.loads(out.stdout)["solutions"]
    assert 2 <= len(solutions) <= 4
    assert min(angle_gap_deg(s, q_deg) for s in solutions) < 1.0


@pytest.mark.parametrize(("q_deg", "xyz", "count"), TABLE2, ids=ROW_IDS)
def test_cli_ik_within_limits_solves_every_printed_row(q_deg, xyz, count) -> None:
    """At the position Table 2 prints (1 mm rounding), within the joint ranges: the table's
    solution count, one of them within 1 deg of the row. Row 1's rounding puts joint 1 0.2 deg
    past its 0 deg limit; the IK limit tolerance takes it at the limit."""
    target = base_p(xyz)
    out = teleprog("kin", "ik", "--robot", "rover", "--xyz", *map(str, target), "--near", *map(str, q_deg), "--json")
    assert out.returncode == 0, out.stderr
    solutions = json.loads(out.stdout)["solutions"]
    assert len(solutions) == count, solutions
    assert angle_gap_deg(solutions[0], q_deg) < 1.0


def test_ik_limit_tolerance_clamps_onto_the_limit_and_can_be_turned_off(rover) -> None:
    q_deg, xyz, _ = TABLE2[0]
    target = base_p(xyz)
    raw = solve_ik(rover, position=target, respect_limits=False)  # nearest to q = 0 first
    assert 0.0 < np.degrees(raw[0][0]) < 0.5  # joint 1 just past its 0 deg limit
    (q,) = solve_ik(rover, position=target)
    assert np.degrees(q[0]) == pytest.approx(0.0, abs=1e-12)  # on the limit, not past it
    assert rover.within_limits(q)
    assert solve_ik(rover, position=target, limit_tolerance=0.0) == []
    out = teleprog("kin", "ik", "--robot", "rover", "--xyz", *map(str, target), "--limit-tolerance", "0")
    assert out.returncode == 1 and "no inverse-kinematics solution" in out.stderr
    bad = teleprog("kin", "ik", "--robot", "rover", "--xyz", *map(str, target), "--limit-tolerance", "-1")
    assert bad.returncode == 1 and bad.stderr.strip().splitlines() == [
        "teleprog: error: --limit-tolerance must be zero or more degrees; got -1.0"
    ]


def test_cli_fk_then_ik_returns_the_exact_angles() -> None:
    q_deg = TABLE2[7][0]  # -190 deg on joint 3: only inside the range as -190, not +170
    fk = json.loads(teleprog("kin", "fk", "--robot", "rover", "--deg", *map(str, q_deg), "--json").stdout)
    out = teleprog("kin", "ik", "--robot", "rover", "--xyz", *map(repr, fk["position"]), "--json")
    assert out.returncode == 0, out.stderr
    solutions = np.array(json.loads(out.stdout)["solutions"])
    assert len(solutions) == 2
    assert min(np.max(np.abs(s - q_deg)) for s in solutions) < 1e-5


def test_cli_out_of_range_joint_is_one_clear_line() -> None:
    out = teleprog("kin", "fk", "--robot", "rover", "--deg", "-30", "-80", "0")
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1
    assert "joint 2" in lines[0] and "outside its range" in lines[0] and "-70.000" in lines[0]
    assert "Traceback" not in out.stderr


def test_cli_unreachable_target_is_one_clear_line() -> None:
    out = teleprog("kin", "ik", "--robot", "rover", "--xyz", "3", "0", "0", "--ignore-limits", "--json")
    assert out.returncode == 1
    assert len(out.stderr.strip().splitlines()) == 1
    assert "no inverse-kinematics solution" in out.stderr


def test_out_of_range_joint_raises_joint_limit_error(rover) -> None:
    with pytest.raises(JointLimitError, match="joint 3 of 'rover'"):
        rover.check_limits(np.radians([-10.0, -10.0, 20.0]))


def test_unreachable_point_has_no_raw_solution(rover) -> None:
    d = rover.description
    assert rover_ik_all(d.joints, d.flange_T_tool, np.array([2.0, 0.0, 0.0])) == []
    # on joint 1's axis the lateral offset L5 cannot be met either
    assert rover_ik_all(d.joints, d.flange_T_tool, np.array([0.0, 0.0, -0.3])) == []


_q = st.tuples(*(st.floats(-1.0, 1.0) for _ in range(3)))


@settings(max_examples=300, deadline=None)
@given(_q)
def test_fk_ik_round_trip_within_limits(u) -> None:
    rover = load_robot("rover")
    q = rover.lower + (np.array(u) + 1.0) / 2.0 * (rover.upper - rover.lower)
    target = rover.fk(q)[:3, 3]
    solutions = solve_ik(rover, position=target, q_near=q)
    assert solutions, f"no solution for q={np.degrees(q)}"
    for s in solutions:
        assert rover.within_limits(s)
        on_limit = np.any(np.isclose(s, rover.lower, rtol=0, atol=1e-12) | np.isclose(s, rover.upper, rtol=0, atol=1e-12))
        # a solution reaches the target exactly, or it is one the IK limit tolerance (0.5 deg)
        # clamped onto a limit, off by at most that turn at the arm's reach (< 1 m)
        reach_error = np.linalg.norm(rover.fk(s)[:3, 3] - target)
        assert reach_error < (np.radians(0.5) * 1.0 * 3 if on_limit else 1e-9), (np.degrees(s), reach_error)
    np.testing.assert_allclose(solutions[0], q, atol=1e-6)


@settings(max_examples=200, deadline=None)
@given(_q)
def test_every_raw_solution_reaches_the_target(u) -> None:
    rover = load_robot("rover")
    q = np.pi * np.array(u)
    target = rover.fk(q)[:3, 3]
    solutions = solve_ik(rover, position=target, respect_limits=False)
    assert 1 <= len(solutions) <= 4
    for s in solutions:
        np.testing.assert_allclose(rover.fk(s)[:3, 3], target, atol=1e-9)
    assert min(angle_gap_deg(np.degrees(s), np.degrees(q)) for s in solutions) < 1e-6


def test_rover_empty_cell_loads() -> None:
    from shared.cells.loader import load_cell

    cell = load_cell(PROJECT_DIR / "assets" / "cells" / "rover_empty.toml")
    assert cell.robot.name == "rover"
    np.testing.assert_allclose(cell.frames["base"][:3, 3], [0.0, 0.0, 0.6])
    base_T_table2 = np.linalg.inv(cell.frames["base"]) @ cell.frames["table2"]
    np.testing.assert_allclose(base_T_table2[:3, 3], -table2_p_base(), atol=1e-12)
