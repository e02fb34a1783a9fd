"""Small helpers shared by the scene modules: poses into viser handles, coloured meshes."""

from __future__ import annotations

import numpy as np
import trimesh
import viser
import viser.transforms as vtf


def wxyz(transform: np.ndarray) -> np.ndarray:
    """The quaternion viser wants for the rotation part of a 4x4 pose."""
    return vtf.SO3.from_matrix(np.asarray(transform)[:3, :3]).wxyz


def place(handle: viser.SceneNodeHandle, transform: np.ndarray) -> None:
    """Set a scene node's pose from a 4x4 pose (parent_T_node)."""
    handle.wxyz = wxyz(transform)
    handle.position = np.asarray(transform)[:3, 3]


def matrix(quat_wxyz: np.ndarray, position: np.ndarray) -> np.ndarray:
    """A 4x4 pose from viser's quaternion and position (the gizmo's pose)."""
    out = np.eye(4)
    out[:3, :3] = vtf.SO3(np.asarray(quat_wxyz)).as_matrix()
    out[:3, 3] = position
    return out


def colored(mesh: trimesh.Trimesh, color: tuple[int, int, int]) -> trimesh.Trimesh:
    out = mesh.copy()
    out.visual = trimesh.visual.ColorVisuals(out, face_colors=np.array([*color, 255], dtype=np.uint8))
    return out
