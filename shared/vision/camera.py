"""A calibrated pinhole camera: intrinsics ``K`` (pixels) and its pose ``world_T_camera`` (the
optical axis is the camera frame's +z, image u to the right along +x, v down along +y)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.errors import InputError
from shared.spatial import invert


@dataclass(frozen=True)
class Camera:
    name: str
    K: np.ndarray  # (3, 3) intrinsics, pixels
    world_T_camera: np.ndarray  # (4, 4)
    width: int
    height: int

    @staticmethod
    def pinhole(name: str, fx: float, fy: float, cx: float, cy: float, world_T_camera: np.ndarray,
                width: int, height: int) -> Camera:
        if not (fx > 0 and fy > 0 and width > 0 and height > 0):
            raise InputError(f"camera {name!r}: focal lengths and image size must be positive")
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        return Camera(name, K, np.asarray(world_T_camera, dtype=float), int(width), int(height))

    @property
    def projection(self) -> np.ndarray:
        """The 3x4 matrix C of §4.2.3 taking world points to homogeneous pixels: K [R | t]."""
        return self.K @ invert(self.world_T_camera)[:3, :]

    def project(self, world_p: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of world points (N, 3); ``InputError`` for a point behind the camera."""
        world_p = np.atleast_2d(np.asarray(world_p, dtype=float))
        camera_T_world = invert(self.world_T_camera)
        camera_p = world_p @ camera_T_world[:3, :3].T + camera_T_world[:3, 3]
        if np.any(camera_p[:, 2] <= 0.0):
            raise InputError(f"camera {self.name!r}: a point lies behind the camera")
        h = camera_p @ self.K.T
        return h[:, :2] / h[:, 2:3]
