"""Workcells are data files; broken ones are rejected with the file, the field and the reason."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shared.cells.loader import CELLS_DIR, DEFAULT_CELL, load_cell
from shared.errors import FileFormatError


def test_default_cell_is_the_peg_in_hole_cell() -> None:
    cell = load_cell(DEFAULT_CELL)
    assert cell.robot.name == "puma562"
    assert set(cell.object_names) == {"table", "plate", "peg"}
    assert {"world", "base", "work"} <= set(cell.frames)
    assert set(cell.features) == {"HOLE1", "HOLE2"}
    assert cell.robot.within_limits(cell.q_home)


def test_peg_fits_its_hole_with_thesis_clearance() -> None:
    """Hole width minus peg width is within the thesis's 0.02-0.04 mm fit clearance."""
    cell = load_cell(DEFAULT_CELL)
    peg = cell.object("peg")
    plate = cell.object("plate")
    peg_width = peg.shapes[0].size[0]
    # the middle column boxes of the plate are exactly as wide as the holes
    hole_width = [s.size[0] for s in plate.shapes if s.size[1] < 0.2][0]
    clearance_mm = (hole_width - peg_width) * 1e3
    assert 0.02 <= clearance_mm <= 0.04
    # the peg stands in HOLE1: same x, y as the hole's mouth
    np.testing.assert_allclose(peg.world_T_object[:2, 3], cell.features["HOLE1"].world_T_feature[:2, 3], atol=1e-12)
    # the gripper at home is above the table
    tcp = cell.world_T_base @ cell.robot.fk(cell.q_home) @ cell.flange_T_tcp
    assert tcp[2, 3] > cell.frame("work")[2, 3]


@pytest.mark.parametrize("path", sorted(CELLS_DIR.glob("*.toml")), ids=lambda p: p.name)
def test_every_shipped_cell_loads(path: Path) -> None:
    cell = load_cell(path)
    assert cell.robot.dof >= 3


BASE = (DEFAULT_CELL).read_text()


@pytest.mark.parametrize(
    ("edit", "field", "message"),
    [
        (lambda s: s.replace('ref = "puma562"', 'ref = "nobot"'), "robot.ref", "unknown robot 'nobot'"),
        (lambda s: s.replace('frame = "work"\nxyz = [0.0, 0.0, -175.0]', 'frame = "desk"\nxyz = [0.0, 0.0, -175.0]'), "objects[0].frame", "'desk' is not defined"),
        (lambda s: s.replace('name = "plate"', 'name = "table"'), "objects[1].name", "used twice"),
        (lambda s: s.replace("q_home = [-15.18, -45.52, 196.42, 0.0, 29.1, 164.82]", "q_home = [0.0, 0.0]"), "robot.q_home", "6 joints"),
        (lambda s: s.replace("q_home = [-15.18, -45.52, 196.42, 0.0, 29.1, 164.82]", "q_home = [0.0, 90.0, 0.0, 0.0, 0.0, 0.0]"), "robot.q_home", "outside"),
        (lambda s: s.replace('{ shape = "box", size = [20.0, 20.0, 80.0] }', '{ shape = "box" }'), "objects[2].shapes[0].size", "needs 'size'"),
        (lambda s: s.replace("quasi = 100.0", "quasi = 5.0"), "zones", "must be below"),
        (lambda s: s.replace('length = "mm"', 'length = "inch"'), "units.length", "'m' or 'mm'"),
        (lambda s: s.replace("[zone_overrides.table]", "[zone_overrides.chair]"), "zone_overrides.chair", "no object"),
        (lambda s: s.replace('shape = "box", size = [20.0, 20.0, 80.0]', 'shape = "mesh", mesh = "missing.stl"'), "objects[2].shapes[0].mesh", "does not exist"),
        (lambda s: s.replace("[robot]", "[robot"), None, "not valid TOML"),
        (lambda s: s.replace("fx = 900.0", "fx = -900.0"), "cameras[0].fx", "greater than 0"),
        (lambda s: s.replace('name = "front"\nxyz', 'name = "front"\nframe = "shelf"\nxyz'), "cameras[0].frame", "not defined"),
        (lambda s: s.replace("keypoints = [[-10.0", "keypoints = [[-10.0, 1.0"), "objects[2].keypoints", ""),
        # numbers no cell can mean, each named by its field (finding 10 of issue 14)
        (lambda s: s.replace("xyz = [0.0, 0.0, 660.0]", "xyz = [inf, 0.0, 660.0]", 1), "robot.xyz[0]", "finite number"),
        (lambda s: s.replace("tcp = { xyz = [0.0, 0.0, 110.0] }", "tcp = { xyz = [0.0, 0.0, 110.0], rpy = [nan, 0, 0] }"), "robot.tcp.rpy[0]", "finite number"),
        (lambda s: s.replace("xyz = [0.0, 0.0, 660.0]", "xyz = [0.0, 0.0, 1e308]", 1), "robot.xyz[2]", "beyond the workspace bound of \u00b1100000 mm"),
        (lambda s: s.replace("size = [20.0, 20.0, 80.0]", "size = [20.0, 0.0, 80.0]"), "objects[2].shapes[0].size[1]", "greater than 0"),
        (lambda s: s.replace("size = [20.0, 20.0, 80.0]", "size = [-20.0, 20.0, 80.0]"), "objects[2].shapes[0].size[0]", "greater than 0"),
        (lambda s: s.replace("color = [200, 160, 40]", "color = [999, -1, 0]"), "objects[2].color[0]", "less than or equal to 255"),
        (lambda s: s.replace('kind = "hole"', 'kind = "wormhole"', 1), "features[0].kind", "'point' or 'hole'"),
        (lambda s: s.replace("quasi = 100.0", "quasi = nan"), "zones.quasi", "finite number"),
    ],
)
def test_broken_cell_files_name_file_and_field(tmp_path, edit, field, message) -> None:
    text = edit(BASE)
    assert text != BASE, "the edit must change the file"
    path = tmp_path / "broken.toml"
    path.write_text(text)
    with pytest.raises(FileFormatError) as info:
        load_cell(path)
    text = str(info.value)
    assert str(path) in text
    if field:
        assert field in text
    assert message in text


def test_rpy_beyond_the_angle_bound_is_refused(tmp_path) -> None:
    text = BASE.replace("rpy = [0.0, 0.0, 0.0]", "rpy = [0.0, 1e308, 0.0]", 1)
    assert text != BASE
    path = tmp_path / "rpy.toml"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=r"robot\.rpy\[1\]: 1e\+308 deg is beyond the angle bound of \u00b1720 deg"):
        load_cell(path)


def test_a_mesh_path_that_is_a_folder_says_so(tmp_path) -> None:
    (tmp_path / "meshes").mkdir()
    path = tmp_path / "folder.toml"
    path.write_text(BASE.replace('shape = "box", size = [20.0, 20.0, 80.0]', 'shape = "mesh", mesh = "meshes"'))
    with pytest.raises(FileFormatError) as info:
        load_cell(path)
    assert "objects[2].shapes[0].mesh" in str(info.value) and "is a folder, not a mesh file" in str(info.value)
    assert "does not exist" not in str(info.value)


def test_every_shipped_cell_loads() -> None:
    for path in sorted(DEFAULT_CELL.parent.glob("*.toml")):
        assert load_cell(path).name, path


def test_missing_and_binary_cell_files(tmp_path) -> None:
    with pytest.raises(FileFormatError, match="does not exist"):
        load_cell(tmp_path / "none.toml")
    binary = tmp_path / "bin.toml"
    binary.write_bytes(b"\xff\xfe\x00\x01")
    with pytest.raises(FileFormatError, match="not a text file"):
        load_cell(binary)
