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


# low ground to high ground: dark slate, earth, sand (light enough at the top to read the relief,
# dark enough everywhere to stand apart from the white floor grid and the light arm)
HEIGHT_STOPS = np.array([[52, 60, 82], [104, 84, 62], [152, 124, 84], [206, 182, 128]], dtype=float)
FLAT_COLOUR = (128, 106, 76)  # a ground with no relief: the earth tone


def height_shaded(mesh: trimesh.Trimesh, world_T_mesh: np.ndarray) -> trimesh.Trimesh:
    """The mesh with each vertex coloured by its height in the world (``HEIGHT_STOPS``, sRGB,
    from the lowest to the highest, 2nd to 98th percentile): a terrain whose relief shows."""
    out = mesh.copy()
    z = np.asarray(out.vertices, dtype=float) @ np.asarray(world_T_mesh)[2, :3] + np.asarray(world_T_mesh)[2, 3]
    lo, hi = np.percentile(z, [2.0, 98.0])
    if hi - lo < 1e-4:
        rgb = np.broadcast_to(np.array(FLAT_COLOUR, dtype=float), (len(z), 3))
    else:
        s = np.clip((z - lo) / (hi - lo), 0.0, 1.0) * (len(HEIGHT_STOPS) - 1)
        i = np.minimum(s.astype(int), len(HEIGHT_STOPS) - 2)
        w = (s - i)[:, None]
        rgb = HEIGHT_STOPS[i] * (1.0 - w) + HEIGHT_STOPS[i + 1] * w
    # glTF vertex colours are linear (the page turns them to sRGB): store the stops' linear values
    linear = np.where(rgb / 255.0 <= 0.04045, rgb / 255.0 / 12.92, ((rgb / 255.0 + 0.055) / 1.055) ** 2.4) * 255.0
    rgba = np.column_stack([np.round(linear), np.full(len(z), 255.0)]).astype(np.uint8)
    out.visual = trimesh.visual.ColorVisuals(out, vertex_colors=rgba)
    return out
