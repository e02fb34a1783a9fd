"""The camera model against an independent oracle: the pinhole formula written out here,
u = fx * X / Z + cx, v = fy * Y / Z + cy on camera-frame coordinates (X, Y, Z), with the camera
frame's axes taken from the pose by hand. Every other vision and locate test makes its pixels
with ``Camera.project`` itself, so only these catch a model that is consistently wrong (cx and cy
swapped, fx and fy swapped, the pose inverted the wrong way).

The image is non-square and cx != cy, fx != fy, so a swap of any pair changes the pixels."""

from __future__ import annotations

import numpy as np
import pytest

from shared.errors import InputError
from shared.vision.camera import Camera

FX, FY, CX, CY = 1100.0, 950.0, 412.5, 187.25
WIDTH, HEIGHT = 800, 400


def oracle(fx: float, fy: float, cx: float, cy: float, world_T_camera: np.ndarray, world_p: np.ndarray) -> np.ndarray:
    """Pixels by the pinhole formula, one point at a time, with no matrix of the code under test."""
    axis_x, axis_y, axis_z = world_T_camera[:3, 0], world_T_camera[:3, 1], world_T_camera[:3, 2]
    origin = world_T_camera[:3, 3]
    out = []
    for p in np.atleast_2d(world_p):
        d = p - origin
        X, Y, Z = float(np.dot(d, axis_x)), float(np.dot(d, axis_y)), float(np.dot(d, axis_z))
        out.append((fx * X / Z + cx, fy * Y / Z + cy))
    return np.array(out)


def pose(rng: np.random.Generator) -> np.ndarray:
    """A random camera pose: a proper rotation (from a QR factorisation) and a position."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q @ np.diag(np.sign(np.diag(r)))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    world_T_camera = np.eye(4)
    world_T_camera[:3, :3] = q
    world_T_camera[:3, 3] = rng.uniform(-1.0, 1.0, 3)
    return world_T_camera


def points_in_front(rng: np.random.Generator, world_T_camera: np.ndarray, n: int) -> np.ndarray:
    """World points 0.2..3 m in front of the camera, spread across (and past) its image."""
    camera_p = np.column_stack([rng.uniform(-1.0, 1.0, n), rng.uniform(-1.0, 1.0, n), rng.uniform(0.2, 3.0, n)])
    return camera_p @ world_T_camera[:3, :3].T + world_T_camera[:3, 3]


def test_camera_at_the_origin_projects_by_the_formula() -> None:
    camera = Camera.pinhole("c", FX, FY, CX, CY, np.eye(4), WIDTH, HEIGHT)
    points = np.array([[0.0, 0.0, 1.0], [0.1, 0.0, 1.0], [0.0, 0.1, 1.0], [0.3, -0.2, 2.0], [-0.05, 0.07, 0.5]])
    expected = np.array([[CX, CY], [CX + 110.0, CY], [CX, CY + 95.0], [CX + 165.0, CY - 95.0], [CX - 110.0, CY + 133.0]])
    np.testing.assert_allclose(camera.project(points), expected, atol=1e-9)
    np.testing.assert_allclose(camera.project(points), oracle(FX, FY, CX, CY, np.eye(4), points), atol=1e-9)


def test_the_principal_point_and_the_image_corners() -> None:
    """A point on the optical axis lands on (cx, cy); points on the rays through the corner
    pixels land on those corners: u spans the width, v the height."""
    rng = np.random.default_rng(3)
    world_T_camera = pose(rng)
    camera = Camera.pinhole("c", FX, FY, CX, CY, world_T_camera, WIDTH, HEIGHT)
    R, t = world_T_camera[:3, :3], world_T_camera[:3, 3]
    for Z in (0.3, 1.0, 2.5):
        corners = np.array([[0.0, 0.0], [WIDTH, 0.0], [0.0, HEIGHT], [WIDTH, HEIGHT], [CX, CY]])
        camera_p = np.column_stack([(corners[:, 0] - CX) / FX * Z, (corners[:, 1] - CY) / FY * Z, np.full(5, Z)])
        np.testing.assert_allclose(camera.project(camera_p @ R.T + t), corners, atol=1e-7)


@pytest.mark.parametrize("seed", range(10))
def test_posed_camera_matches_the_formula(seed: int) -> None:
    rng = np.random.default_rng(seed)
    world_T_camera = pose(rng)
    camera = Camera.pinhole("c", FX, FY, CX, CY, world_T_camera, WIDTH, HEIGHT)
    points = points_in_front(rng, world_T_camera, 50)
    expected = oracle(FX, FY, CX, CY, world_T_camera, points)
    np.testing.assert_allclose(camera.project(points), expected, atol=1e-7)
    # the 3x4 projection matrix agrees with the same oracle
    h = np.column_stack([points, np.ones(len(points))]) @ camera.projection.T
    np.testing.assert_allclose(h[:, :2] / h[:, 2:3], expected, atol=1e-7)


def test_the_intrinsics_are_laid_out_as_the_formula_says() -> None:
    camera = Camera.pinhole("c", FX, FY, CX, CY, np.eye(4), WIDTH, HEIGHT)
    np.testing.assert_array_equal(camera.K, [[FX, 0.0, CX], [0.0, FY, CY], [0.0, 0.0, 1.0]])
    assert (camera.width, camera.height) == (WIDTH, HEIGHT)


def test_a_point_behind_the_camera_is_refused() -> None:
    camera = Camera.pinhole("c", FX, FY, CX, CY, np.eye(4), WIDTH, HEIGHT)
    with pytest.raises(InputError):
        camera.project(np.array([[0.0, 0.0, -1.0]]))


def test_the_cell_files_camera_keeps_its_intrinsics() -> None:
    """The loader hands the file's fx, fy, cx, cy to the model in their places."""
    import tomllib

    from shared.cells.loader import DEFAULT_CELL, load_cell

    spec = tomllib.loads(DEFAULT_CELL.read_text())["cameras"][0]
    camera = load_cell(DEFAULT_CELL).cameras[spec["name"]]
    assert spec["cx"] != spec["cy"]  # the premise: a swap would show
    np.testing.assert_array_equal(camera.K, [[spec["fx"], 0.0, spec["cx"]], [0.0, spec["fy"], spec["cy"]], [0.0, 0.0, 1.0]])
    assert (camera.width, camera.height) == (spec["width"], spec["height"])
    # a point straight ahead of the camera lands on the principal point
    ahead = camera.world_T_camera[:3, 3] + 0.7 * camera.world_T_camera[:3, 2]
    np.testing.assert_allclose(camera.project(ahead)[0], [spec["cx"], spec["cy"]], atol=1e-9)
