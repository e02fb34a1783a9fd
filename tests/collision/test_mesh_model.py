"""Bad meshes are refused with an error naming the file; good ones keep the UI's triangle ids."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision.mesh_model import MeshError, body_mesh, body_mesh_from_arrays
from shared.errors import FileFormatError
from shared.robots.description import LinkShape
from shared.robots.shapes import link_meshes


def _mesh_shape(path: Path) -> LinkShape:
    return LinkShape(kind="mesh", link_T_shape=np.eye(4), mesh_path=str(path))


def test_triangle_ids_match_the_displayed_link_meshes() -> None:
    cell = load_cell(DEFAULT_CELL)
    for link, shapes in cell.robot.shapes.items():
        body = body_mesh(f"link{link}", shapes)
        shown = link_meshes(shapes)
        np.testing.assert_array_equal(body.faces, shown.faces)
        np.testing.assert_allclose(body.vertices, shown.vertices)


def test_empty_nan_and_out_of_range_are_refused() -> None:
    with pytest.raises(MeshError, match="empty"):
        body_mesh_from_arrays("thing", np.zeros((0, 3)), np.zeros((0, 3), dtype=int))
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    with pytest.raises(MeshError, match="NaN"):
        body_mesh_from_arrays("thing", np.where(np.eye(3, dtype=bool), np.nan, v), np.array([[0, 1, 2]]), require_manifold=False)
    with pytest.raises(MeshError, match="face indices"):
        body_mesh_from_arrays("thing", v, np.array([[0, 1, 3]]))
    with pytest.raises(MeshError, match="zero area"):
        body_mesh_from_arrays("thing", np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), np.array([[0, 1, 2]]))


def test_non_manifold_mesh_file_is_refused_naming_the_file(tmp_path: Path) -> None:
    # three triangles sharing one edge
    path = tmp_path / "fin.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 2 5\n")
    with pytest.raises(MeshError) as err:
        body_mesh("link3", (_mesh_shape(path),))
    assert str(path) in str(err.value) and "manifold" in str(err.value)
    assert isinstance(err.value, FileFormatError)


def test_unreadable_and_nan_mesh_files_name_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "nan.obj"
    bad.write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(FileFormatError) as err:
        body_mesh("peg", (_mesh_shape(bad),))
    assert str(bad) in str(err.value)
    empty = tmp_path / "empty.obj"
    empty.write_text("# nothing\n")
    with pytest.raises(FileFormatError) as err:
        body_mesh("peg", (_mesh_shape(empty),))
    assert str(empty) in str(err.value)


def test_degenerate_triangles_are_kept_and_counted() -> None:
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]])
    body = body_mesh_from_arrays("thing", v, np.array([[0, 1, 2], [0, 1, 3]]), require_manifold=False)
    assert body.n_degenerate == 1 and len(body.faces) == 2
