"""``teleprog collide``, ``teleprog miz`` and ``teleprog bench collision`` as a user runs them."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from support import PROJECT_DIR

TELEPROG = PROJECT_DIR / ".venv" / "bin" / "teleprog"


def run(*args: str, timeout: float = 240.0) -> subprocess.CompletedProcess:
    return subprocess.run([str(TELEPROG), *args], capture_output=True, text=True, timeout=timeout, cwd=PROJECT_DIR)


def one_line_error(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("teleprog: error:"), proc.stderr
    return lines[0]


def test_collide_json_free_pose() -> None:
    proc = run("collide", "--deg", "-15.18", "-45.52", "196.42", "0", "29.1", "164.82", "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["collision"] is False and doc["pairs"] == []
    assert doc["min_distance"] > 0 and doc["unit"] == "m"
    assert doc["zone"] == "quasi"  # the ready pose hovers over the peg (quasi zone at 100 mm)


def test_collide_json_reports_pairs_and_triangles() -> None:
    proc = run("collide", "--cell", "assets/cells/peg_in_hole.toml", "--deg", "0", "-30", "180", "0", "45", "0", "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["collision"] is True and doc["min_distance"] == 0.0 and doc["zone"] == "operation"
    (pair,) = doc["pairs"]
    assert {pair["a"], pair["b"]} == {"link6", "plate"}
    assert pair["triangles_a"] and pair["triangles_b"]
    assert pair["triangles_a"] == sorted(set(pair["triangles_a"]))
    human = run("collide", "--deg", "0", "-30", "180", "0", "45", "0")
    assert human.returncode == 0 and "collision: yes" in human.stdout and "zone: operation" in human.stdout


def test_collide_bad_input_is_one_line() -> None:
    assert "6 joints" in one_line_error(run("collide", "--deg", "0", "0", "0", "--json"))
    assert "joint 2" in one_line_error(run("collide", "--deg", "0", "90", "0", "0", "0", "0"))
    assert "nowhere.toml" in one_line_error(run("collide", "--cell", "nowhere.toml", "--deg", *["0"] * 6))


def _cell_with_mesh(tmp_path: Path, mesh_text: str, name: str) -> Path:
    mesh = tmp_path / name
    mesh.write_text(mesh_text)
    cell_text = (PROJECT_DIR / "assets" / "cells" / "peg_in_hole.toml").read_text()
    cell_text += f'\n[[objects]]\nname = "bad"\nxyz = [0.0, 600.0, 0.0]\nshapes = [{{ shape = "mesh", mesh = "{mesh}" }}]\n'
    cell = tmp_path / f"cell_{name}.toml"
    cell.write_text(cell_text)
    return cell


@pytest.mark.parametrize(
    "name, text, says",
    [
        ("fin.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 2 5\n", "manifold"),
        ("empty.obj", "# nothing\n", ""),
        ("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", ""),
    ],
)
def test_bad_mesh_in_a_cell_is_named(tmp_path: Path, name: str, text: str, says: str) -> None:
    cell = _cell_with_mesh(tmp_path, text, name)
    line = one_line_error(run("collide", "--cell", str(cell), "--deg", *["0"] * 6, "--json"))
    assert name in line and says in line


def test_miz_json_gives_polygons_in_radians() -> None:
    proc = run("miz", "--robot", "puma562", "--joints", "2", "3", "--step", "4", "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["unit"] == "rad" and doc["joints"] == [2, 3] and doc["robot"] == "puma562"
    assert doc["zones"] and doc["colliding_samples"] > 0
    for z in doc["zones"]:
        v = np.array(z["vertices"])
        assert v.shape[1] == 2 and len(v) >= 3 and z["origin"] == "generated"
        assert np.all(np.abs(v) < 2 * np.pi)  # radians, not degrees
    # a move whose goal lies where the upper arm meets the pedestal is refused
    proc = run("miz", "--robot", "puma562", "--joints", "2", "3", "--step", "4",
               "--from", "0", "0", "90", "0", "0", "0", "--to", "0", "44.5", "90", "0", "0", "0", "--json")
    check = json.loads(proc.stdout)["check"]
    assert check["kind"] == "refused" and "inside" in check["reason"]


def test_miz_bad_input_is_one_line() -> None:
    assert "joint 7" in one_line_error(run("miz", "--robot", "puma562", "--joints", "2", "7", "--json"))
    assert "2 joint numbers" in one_line_error(run("miz", "--robot", "puma562", "--joints", "2", "--json"))
    assert "puma999" in one_line_error(run("miz", "--robot", "puma999", "--joints", "2", "3"))
    usage = run("miz", "--robot", "puma562")
    assert usage.returncode == 2


def test_bench_collision_json_small_run() -> None:
    proc = run("bench", "collision", "--drag-poses", "60", "--random-poses", "30", "--distance-poses", "3", "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    for stream in ("dragging", "random"):
        s = doc["streams"][stream]
        assert set(s["check_us"]) == {"ours", "coal", "fcl"} == set(s["distance_us"]) == set(s["first_hit_us"])
        assert all(v > 0 for v in s["check_us"].values())
        assert set(s["ratio_check"]) == {"coal", "fcl"}
    assert one_line_error(run("bench", "collision", "--engines", "ours,bullet"))
    assert run("bench").returncode == 2  # which benchmark: a usage error
