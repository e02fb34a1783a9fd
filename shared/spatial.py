"""Small rigid-transform helpers on plain numpy arrays.

Conventions (see ``shared/CONVENTIONS.md``): SI units, right-handed frames, z up,
homogeneous transforms as ``(4, 4)`` arrays named ``a_T_b`` (maps coordinates in frame b
to frame a), roll-pitch-yaw as fixed-axis X-Y-Z angles: ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
"""

from __future__ import annotations

import numpy as np


def rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    """Fixed-axis X-Y-Z roll, pitch, yaw (rad) -> rotation matrix (3, 3)."""
    roll, pitch, yaw = (float(v) for v in rpy)
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def matrix_to_rpy(rotation: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) -> fixed-axis X-Y-Z roll, pitch, yaw (rad), pitch in [-pi/2, pi/2]."""
    r = np.asarray(rotation, dtype=float)
    pitch = np.arctan2(-r[2, 0], np.hypot(r[0, 0], r[1, 0]))
    if np.hypot(r[0, 0], r[1, 0]) < 1e-12:  # gimbal lock: put everything in roll
        yaw = 0.0
        roll = np.arctan2(r[0, 1], r[1, 1]) if pitch > 0 else np.arctan2(-r[0, 1], r[1, 1])
    else:
        roll = np.arctan2(r[2, 1], r[2, 2])
        yaw = np.arctan2(r[1, 0], r[0, 0])
    return np.array([roll, pitch, yaw])


def make_transform(rotation: np.ndarray | None = None, translation: np.ndarray | None = None) -> np.ndarray:
    """Build ``(4, 4)`` from a rotation ``(3, 3)`` and a translation ``(3,)``."""
    t = np.eye(4)
    if rotation is not None:
        t[:3, :3] = rotation
    if translation is not None:
        t[:3, 3] = translation
    return t


def pose_to_transform(xyz: np.ndarray, rpy: np.ndarray) -> np.ndarray:
    return make_transform(rpy_to_matrix(rpy), np.asarray(xyz, dtype=float))


def invert(a_T_b: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform without a general matrix inverse."""
    r = a_T_b[:3, :3]
    out = np.eye(4)
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ a_T_b[:3, 3]
    return out


def rotation_angle(rotation: np.ndarray) -> float:
    """Angle (rad) of a rotation matrix, robust near 0 and pi."""
    c = (np.trace(rotation) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def log_so3(rotation: np.ndarray) -> np.ndarray:
    """Rotation vector (axis * angle) of a rotation matrix."""
    angle = rotation_angle(rotation)
    if angle < 1e-9:
        return np.array([rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0], rotation[1, 0] - rotation[0, 1]]) / 2.0
    if np.pi - angle < 1e-6:
        # near pi: axis from the diagonal
        m = (rotation + np.eye(3)) / 2.0
        k = int(np.argmax(np.diag(m)))
        axis = m[:, k] / np.sqrt(max(m[k, k], 1e-300))
        return axis / np.linalg.norm(axis) * angle
    w = np.array([rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0], rotation[1, 0] - rotation[0, 1]])
    return w * (angle / (2.0 * np.sin(angle)))


def exp_so3(rotvec: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    v = np.asarray(rotvec, dtype=float)
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        return np.eye(3)
    k = v / angle
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)
