"""The pose of a known object from four non-coplanar feature points in one calibrated image
(thesis §4.2.3, correction of the virtual objects).

The thesis writes, for each feature point ``P_i`` (homogeneous, object frame) seen at pixel
``Q_i = (u_i, v_i, 1)``, ``Z_i Q_i = C M P_i`` with ``C`` the camera's projection matrix, ``M``
the object's pose in the world and ``Z_i`` the point's depth, and solves the four together.
Written in the camera frame, ``Z_i b_i = N P_i`` with ``b_i = K^-1 Q_i`` and ``N`` the object in
the camera frame. Four non-coplanar points make ``P = [P_1 .. P_4]`` invertible, so
``N = B diag(Z) P^-1``: the pose is linear in the four depths, and the depths are fixed by ``N``'s
rotation block being a rotation. That is solved by alternating the nearest rotation (polar
decomposition) with the depths' linear least squares; the result is then refined by minimising
the reprojection error over all points (Gauss-Newton on the pose), which is what an image with
noise calls for. The reprojection residual (pixels) says how well the picked points fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.errors import InputError
from shared.spatial import exp_so3
from shared.vision.camera import Camera

#: the four points' homogeneous matrix must be at least this well conditioned (relative volume)
COPLANAR_TOL = 1e-6


@dataclass(frozen=True)
class LocatedPose:
    world_T_object: np.ndarray  # (4, 4)
    residual_px: float  # RMS reprojection error over the points
    depths: np.ndarray  # (n,) depth of each point from the camera (m)


def _nearest_rotation(G: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(G)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, -1] *= -1.0
        R = U @ Vt
    return R


def _reprojection(camera_T_object: np.ndarray, object_p: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    camera_p = object_p @ camera_T_object[:3, :3].T + camera_T_object[:3, 3]
    h = camera_p @ K.T
    return h[:, :2] / h[:, 2:3], camera_p


def locate_object(camera: Camera, object_p: np.ndarray, pixels: np.ndarray, iterations: int = 20) -> LocatedPose:
    """``world_T_object`` from feature points ``object_p`` (n >= 4, object frame, m; the first
    four non-coplanar) seen at ``pixels`` (n, 2)."""
    object_p = np.asarray(object_p, dtype=float)
    pixels = np.asarray(pixels, dtype=float)
    if object_p.ndim != 2 or object_p.shape[1] != 3 or object_p.shape[0] < 4:
        raise InputError(f"locating an object needs at least 4 feature points (x, y, z), got shape {object_p.shape}")
    if pixels.shape != (object_p.shape[0], 2):
        raise InputError(f"need one pixel (u, v) per feature point: {object_p.shape[0]} points, pixels of shape {pixels.shape}")
    if not (np.all(np.isfinite(object_p)) and np.all(np.isfinite(pixels))):
        raise InputError("feature points and pixels must be finite numbers")
    K = camera.K
    P = np.vstack([object_p[:4].T, np.ones(4)])  # (4, 4) homogeneous, one point a column
    scale = np.max(np.ptp(object_p[:4], axis=0)) or 1.0
    if abs(np.linalg.det((object_p[1:4] - object_p[0]) / scale)) < COPLANAR_TOL:
        raise InputError("the four feature points are coplanar (or repeated): pick four that span a volume")
    W = np.linalg.inv(P)
    B = np.linalg.solve(K, np.vstack([pixels[:4].T, np.ones(4)]))  # rays with z = 1, (3, 4)
    # G(d) = sum_i d_i b_i w_i^T; vec(G) = A d
    A = np.stack([np.outer(B[:, i], W[i, :3]).ravel() for i in range(4)], axis=1)
    d = np.ones(4)
    d /= np.linalg.norm(A @ d) / np.sqrt(3.0)  # a rotation's Frobenius norm is sqrt(3)
    for _ in range(200):
        R = _nearest_rotation((A @ d).reshape(3, 3))
        d_new = np.linalg.lstsq(A, R.ravel(), rcond=None)[0]
        if np.max(np.abs(d_new - d)) <= 1e-13 * max(1.0, np.max(np.abs(d))):
            d = d_new
            break
        d = d_new
    if np.any(d <= 0.0):
        raise InputError("the feature points would lie behind the camera: check which pixel belongs to which point")
    camera_T_object = np.eye(4)
    camera_T_object[:3, :3] = _nearest_rotation((A @ d).reshape(3, 3))
    camera_T_object[:3, 3] = B @ (d * W[:, 3])
    # refine on the reprojection error of every point (the linear step uses exactly four)
    for _ in range(iterations):
        uv, camera_p = _reprojection(camera_T_object, object_p, K)
        r = (uv - pixels).ravel()
        J = np.zeros((r.size, 6))
        for k in range(object_p.shape[0]):
            x, y, z = camera_p[k]
            fx, fy = K[0, 0], K[1, 1]
            d_uv_d_p = np.array([[fx / z, 0.0, -fx * x / z**2], [0.0, fy / z, -fy * y / z**2]])
            # perturbation camera_T_object <- [exp(w) | v] * camera_T_object: dp = v + w x p
            skew = np.array([[0.0, z, -y], [-z, 0.0, x], [y, -x, 0.0]])
            J[2 * k : 2 * k + 2] = d_uv_d_p @ np.hstack([np.eye(3), skew])
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        update = np.eye(4)
        update[:3, :3] = exp_so3(step[3:])
        update[:3, 3] = step[:3]
        camera_T_object = update @ camera_T_object
        if np.linalg.norm(step) < 1e-12:
            break
    uv, camera_p = _reprojection(camera_T_object, object_p, K)
    if np.any(camera_p[:, 2] <= 0.0):
        raise InputError("the located object would lie behind the camera: the pixels do not fit the feature points")
    residual = float(np.sqrt(np.mean(np.sum((uv - pixels) ** 2, axis=1))))
    return LocatedPose(camera.world_T_camera @ camera_T_object, residual, camera_p[:, 2].copy())
