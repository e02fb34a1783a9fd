"""Pose of a known object from four non-coplanar feature points in one calibrated image
(thesis §4.2.3): exact on exact pixels, sub-millimetre under pixel noise, clear refusals."""

from __future__ import annotations

import numpy as np
import pytest

from shared.errors import InputError
from shared.spatial import pose_to_transform
from shared.vision.camera import Camera
from shared.vision.pose import locate_object

# a 40 x 30 x 80 mm block's corners: three of the top face and one of the bottom (non-coplanar)
KEYPOINTS = np.array([[-0.02, -0.015, 0.04], [0.02, -0.015, 0.04], [0.02, 0.015, 0.04], [-0.02, -0.015, -0.04]])


def camera_looking_at(target: np.ndarray, position: np.ndarray, f: float = 900.0) -> Camera:
    z = (target - position) / np.linalg.norm(target - position)
    y = np.array([0.0, 0.0, -1.0]) - np.dot([0.0, 0.0, -1.0], z) * z
    y /= np.linalg.norm(y)
    world_T_camera = np.eye(4)
    world_T_camera[:3, :3] = np.stack([np.cross(y, z), y, z], axis=1)
    world_T_camera[:3, 3] = position
    return Camera.pinhole("test", f, f, 320.0, 240.0, world_T_camera, 640, 480)


def random_case(rng: np.random.Generator):
    target = rng.uniform([-0.3, -0.3, 0.0], [0.3, 0.3, 0.3])
    position = target + rng.uniform(0.4, 1.0) * np.array([rng.uniform(-0.5, 0.5), -1.0, rng.uniform(0.3, 1.2)])
    camera = camera_looking_at(target, position)
    world_T_object = pose_to_transform(target, rng.uniform(-0.5, 0.5, 3))
    world_p = KEYPOINTS @ world_T_object[:3, :3].T + world_T_object[:3, 3]
    return camera, world_T_object, camera.project(world_p)


@pytest.mark.parametrize("seed", range(25))
def test_exact_pixels_give_the_exact_pose(seed: int) -> None:
    camera, truth, pixels = random_case(np.random.default_rng(seed))
    located = locate_object(camera, KEYPOINTS, pixels)
    np.testing.assert_allclose(located.world_T_object, truth, atol=1e-9)
    assert located.residual_px < 1e-6 and np.all(located.depths > 0)


def rms_residual(camera: Camera, world_T_object: np.ndarray, points: np.ndarray, pixels: np.ndarray) -> float:
    uv = camera.project(points @ world_T_object[:3, :3].T + world_T_object[:3, 3])
    return float(np.sqrt(np.mean(np.sum((uv - pixels) ** 2, axis=1))))


def test_under_pixel_noise_the_pose_fits_at_least_as_well_as_the_truth() -> None:
    """With noisy pixels the best pose is the one that reprojects best (the truth does not);
    the lateral error is small, the depth along the camera's ray is the weak direction."""
    rng = np.random.default_rng(7)
    lateral = []
    for _ in range(200):
        camera, truth, pixels = random_case(rng)
        noisy = pixels + rng.normal(0.0, 0.5, pixels.shape)
        located = locate_object(camera, KEYPOINTS, noisy)
        assert located.residual_px <= rms_residual(camera, truth, KEYPOINTS, noisy) + 1e-9
        assert located.residual_px == pytest.approx(rms_residual(camera, located.world_T_object, KEYPOINTS, noisy))
        err = located.world_T_object[:3, 3] - truth[:3, 3]
        ray = truth[:3, 3] - camera.world_T_camera[:3, 3]
        ray /= np.linalg.norm(ray)
        lateral.append(np.linalg.norm(err - np.dot(err, ray) * ray))
    assert np.median(lateral) < 0.001


def test_more_points_than_four_are_all_used() -> None:
    rng = np.random.default_rng(3)
    more = np.vstack([KEYPOINTS, [[-0.02, 0.015, -0.04], [0.02, 0.015, -0.04]]])
    for _ in range(20):
        camera, truth, _ = random_case(rng)
        pixels = camera.project(more @ truth[:3, :3].T + truth[:3, 3])
        noisy = pixels + rng.normal(0.0, 0.5, pixels.shape)
        six = locate_object(camera, more, noisy)
        assert six.residual_px <= rms_residual(camera, truth, more, noisy) + 1e-9
    exact = locate_object(camera, more, pixels)
    np.testing.assert_allclose(exact.world_T_object, truth, atol=1e-9)


def test_coplanar_points_are_refused() -> None:
    camera, truth, _ = random_case(np.random.default_rng(1))
    flat = KEYPOINTS.copy()
    flat[3] = [-0.02, 0.015, 0.04]  # all four on the top face
    pixels = camera.project(flat @ truth[:3, :3].T + truth[:3, 3])
    with pytest.raises(InputError, match="coplanar"):
        locate_object(camera, flat, pixels)


def test_bad_input_is_refused_with_what_is_wrong() -> None:
    camera, _, pixels = random_case(np.random.default_rng(2))
    with pytest.raises(InputError, match="at least 4"):
        locate_object(camera, KEYPOINTS[:3], pixels[:3])
    with pytest.raises(InputError, match="one pixel"):
        locate_object(camera, KEYPOINTS, pixels[:3])
    with pytest.raises(InputError, match="finite"):
        locate_object(camera, KEYPOINTS, np.where(np.eye(4, 2, dtype=bool), np.nan, pixels))


def test_swapped_points_do_not_fit() -> None:
    camera, _, pixels = random_case(np.random.default_rng(4))
    swapped = pixels[[1, 0, 2, 3]]
    try:
        located = locate_object(camera, KEYPOINTS, swapped)
    except InputError:
        return  # behind the camera: refused outright
    assert located.residual_px > 3.0  # the caller refuses a fit this poor
