"""Instrument placement on the rover terrain cell, and the ``teleprog terrain`` commands."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from shared.errors import InputError, UnreachableError
from shared.language.formatter import format_program
from shared.language.parser import parse_program
from shared.language.statements import Move
from shared.robots.ik import solve_ik
from shared.terrain.placement import MAX_STANDOFF, plan_placement, require_placement, terrain_point_at

from conftest import CELL


def test_placement_meets_every_condition(cell_terrain, cell):
    checker = cell_terrain.checker
    target = terrain_point_at(checker, 0.70, 0.0)
    result = plan_placement(checker, target, margin=0.02)
    assert result.candidates
    n = result.world_n_surface
    assert n[2] > 0.8 and np.linalg.norm(n) == pytest.approx(1.0)
    clearances = [c.clearance for c in result.candidates if c.q_approach is not None]
    assert clearances == sorted(clearances, reverse=True)
    groups = np.zeros(len(checker.arm.shapes), np.int64)
    groups[checker.arm.tool_shape] = 1
    for c in result.candidates:
        assert cell.robot.within_limits(c.q)
        world_p_c = (cell.world_T_base @ cell.robot.fk(c.q))[:3, 3]
        offset = world_p_c - target
        # C on the normal through the target, within 30 mm of the surface
        assert np.linalg.norm(offset - np.dot(offset, n) * n) < 1e-6
        assert 0 < np.dot(offset, n) <= MAX_STANDOFF + 1e-9
        d, *_ = checker.group_distances(c.q, groups, 2)
        assert d[0] >= 0.02 and d[1] > 0
        assert d[0] == pytest.approx(c.clearance)
    # the program: approach then final pose; it round-trips through the statement language
    moves = [s for s in result.program if isinstance(s, Move)]
    assert np.allclose(moves[-1].joints, result.best.q, atol=np.radians(0.001))
    text = format_program(result.program)
    assert "EVENT instrument_placed" in text
    parsed = parse_program(text)
    assert not parsed.errors
    assert format_program(parsed.statements) == text


def test_placement_counts_all_ik_branches(cell_terrain, cell):
    """Every IK solution within the ranges is considered: none is missed by the dedupe."""
    checker = cell_terrain.checker
    target = terrain_point_at(checker, 0.70, -0.05)
    result = plan_placement(checker, target, margin=0.0, head_margin=-1.0)
    base_T_world = np.linalg.inv(cell.world_T_base)
    p = target + 0.5 * MAX_STANDOFF * result.world_n_surface
    sols = solve_ik(cell.robot, position=(base_T_world @ np.append(p, 1))[:3])
    for q in sols:
        assert any(np.max(np.abs(q - c.q)) < np.radians(10) for c in result.candidates)


def test_placement_errors(cell_terrain):
    checker = cell_terrain.checker
    with pytest.raises(InputError, match="not on the terrain"):
        plan_placement(checker, np.array([0.70, 0.0, 2.0]))
    with pytest.raises(InputError, match="outside the terrain"):
        terrain_point_at(checker, 5.0, 5.0)
    far = terrain_point_at(checker, 1.00, -0.30)  # on the terrain, out of the arm's reach
    with pytest.raises(UnreachableError, match="no safe instrument placement"):
        require_placement(plan_placement(checker, far))


def _teleprog(*args):
    return subprocess.run([sys.executable, "-m", "server.cli", *args], capture_output=True, text=True, timeout=120)


def test_cli_generate_info_check_place(tmp_path):
    out = tmp_path / "t.ply"
    gen = _teleprog("terrain", "generate", "--out", str(out), "--points", "3000", "--json")
    assert gen.returncode == 0, gen.stderr
    assert json.loads(gen.stdout)["points"] == 3000
    info = _teleprog("terrain", "info", str(out), "--json")
    assert info.returncode == 0, info.stderr
    data = json.loads(info.stdout)
    assert 0 < data["kept"] <= 3000 and data["triangles"] > data["kept"]
    check = _teleprog("terrain", "check", "--cell", str(CELL), "--deg", "-30", "-10", "-60", "--json")
    assert check.returncode == 0, check.stderr
    c = json.loads(check.stdout)
    assert c["exact"]["distance"] > 0 and c["sensors"]["count"] > 0
    place = _teleprog("terrain", "place", "--cell", str(CELL), "--target", "700", "0", "--json")
    assert place.returncode == 0, place.stderr
    assert "MOVE" in json.loads(place.stdout)["program"]
    bad = _teleprog("terrain", "check", "--cell", str(CELL), "--deg", "10", "0", "0")
    assert bad.returncode == 1 and "outside its range" in bad.stderr


def test_committed_cell_terrain_is_the_generated_one(tmp_path):
    """assets/terrains/lunar_cell.ply is what the generator command in the cell file writes."""
    out = tmp_path / "cell.ply"
    gen = _teleprog("terrain", "generate", "--out", str(out), "--points", "12000", "--origin", "350", "-350",
                    "--size", "700", "700", "--mesh")
    assert gen.returncode == 0, gen.stderr
    from shared.terrain.cloud import read_ply

    v_new, f_new = read_ply(out)
    v_old, f_old = read_ply(CELL.parent.parent / "terrains" / "lunar_cell.ply")
    np.testing.assert_allclose(v_new, v_old, atol=1e-6)
    np.testing.assert_array_equal(f_new, f_old)
