"""Point-cloud loading: every format, units and up axes, and one clear error per bad input."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from shared.errors import FileFormatError, InputError
from shared.terrain.cloud import cloud_from_array, load_point_cloud, ply_bytes, read_ply
from shared.terrain.generator import generate_points, make_spec


@pytest.fixture(scope="module")
def points():
    return generate_points(make_spec(seed=3, origin=(0, 0), size=(1, 1)), 2000)


def test_binary_ply_round_trip_with_faces(tmp_path, points):
    faces = np.array([[0, 1, 2], [2, 3, 4]])
    (tmp_path / "a.ply").write_bytes(ply_bytes(points, faces))
    v, f = read_ply(tmp_path / "a.ply")
    np.testing.assert_allclose(v, points, atol=1e-6)  # float32 on disk
    np.testing.assert_array_equal(f, faces)
    cloud = load_point_cloud(tmp_path / "a.ply")
    assert len(cloud) == len(points)


def test_ascii_ply_with_extra_properties(tmp_path):
    text = "\n".join([
        "ply", "format ascii 1.0", "comment from a camera", "element vertex 4", "property float x", "property float y",
        "property float z", "property uchar red", "element face 1", "property list uchar int vertex_indices", "end_header",
        "0 0 0 10", "1 0 0.1 20", "0 1 0.2 30", "1 1 0.3 40", "3 0 1 2",
    ]) + "\n"
    (tmp_path / "b.ply").write_text(text)
    v, f = read_ply(tmp_path / "b.ply")
    np.testing.assert_allclose(v[:, 2], [0, 0.1, 0.2, 0.3])
    np.testing.assert_array_equal(f, [[0, 1, 2]])


def test_big_endian_ply(tmp_path):
    pts = np.array([[0, 0, 0], [1, 0, 0.5], [0, 1, 0.25]], dtype=">f8")
    header = "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nend_header\n"
    (tmp_path / "c.ply").write_bytes(header.encode() + pts.tobytes())
    np.testing.assert_allclose(load_point_cloud(tmp_path / "c.ply").points, pts.astype(float))


@pytest.mark.parametrize("suffix", [".xyz", ".csv", ".txt", ".npy"])
def test_text_and_npy_formats(tmp_path, points, suffix):
    path = tmp_path / f"p{suffix}"
    if suffix == ".npy":
        np.save(path, points)
    else:
        header = "x,y,z\n" if suffix == ".csv" else "# a comment\n"
        body = "\n".join(("{:.6f},{:.6f},{:.6f}" if suffix == ".csv" else "{:.6f} {:.6f} {:.6f}").format(*p) for p in points)
        path.write_text(header + body + "\n")
    np.testing.assert_allclose(load_point_cloud(path).points, points, atol=1e-6)


def test_millimetres_and_y_up(tmp_path, points):
    np.save(tmp_path / "mm.npy", points * 1e3)
    np.testing.assert_allclose(load_point_cloud(tmp_path / "mm.npy", unit="mm").points, points)
    y_up = points[:, [1, 2, 0]]  # file axes: height is the file's y
    np.save(tmp_path / "y.npy", y_up)
    np.testing.assert_allclose(load_point_cloud(tmp_path / "y.npy", up="y").points, points)
    with pytest.raises(FileFormatError, match="not a 2.5D terrain"):
        load_point_cloud(tmp_path / "y.npy")  # read with z up it is a wall


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("empty.xyz", b"", "file is empty"),
        ("bad.ply", b"not a ply at all", "not a PLY file"),
        ("short.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nproperty float y\n"
                      b"property float z\nend_header\n\x00\x00", "ends before"),
        ("noxyz.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\nend_header\n1\n", "no x, y, z"),
        ("words.xyz", b"0 0 0\n1 1 1\nfoo bar baz\n", "line 3 is not three numbers"),
        ("two.xyz", b"0 0\n", "needs x y z"),
        ("nan.xyz", b"0 0 0\n1 0 nan\n0 1 0\n", "NaN or infinite"),
        ("few.xyz", b"0 0 0\n1 0 0\n", "at least 3 points"),
        ("kind.las", b"xxxx", "unknown point cloud type"),
    ],
)
def test_bad_files_raise_one_line_errors(tmp_path, name, content, message):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(FileFormatError, match=message) as info:
        load_point_cloud(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_missing_file_and_bad_npy(tmp_path):
    with pytest.raises(FileFormatError, match="does not exist"):
        load_point_cloud(tmp_path / "none.ply")
    np.save(tmp_path / "flat.npy", np.zeros(5))
    with pytest.raises(FileFormatError, match=r"needs \(N, 3\)"):
        load_point_cloud(tmp_path / "flat.npy")


def test_closed_surface_is_not_25d():
    rng = np.random.default_rng(0)
    sphere = rng.normal(size=(5000, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    with pytest.raises(InputError, match="not a 2.5D terrain.*overhangs"):
        cloud_from_array(sphere)


def test_steep_rocks_still_25d():
    # the generator's half-buried rocks are steep but a height field
    pts = generate_points(make_spec(seed=5, origin=(0, 0), size=(1, 1), rocks_per_m2=40), 20000)
    assert len(cloud_from_array(pts)) == 20000


def test_cli_reports_bad_file_in_one_line(tmp_path):
    bad = tmp_path / "nan.xyz"
    bad.write_text("0 0 0\n1 0 nan\n0 1 0\n")
    proc = subprocess.run([sys.executable, "-m", "server.cli", "terrain", "info", str(bad)], capture_output=True, text=True)
    assert proc.returncode == 1
    assert "NaN" in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
