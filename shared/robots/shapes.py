"""Turn link and object shapes into triangle meshes (in the shape's own frame or posed)."""

from __future__ import annotations

import numpy as np
import trimesh

from shared.errors import FileFormatError
from shared.robots.description import LinkShape

#: facets around a round shape; enough to look round and to collide within a fraction of a mm
ROUND_SECTIONS = 24


def load_mesh_file(path: str, scale: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> trimesh.Trimesh:
    """Load a triangle mesh, checked: not empty, finite vertices, valid face indices."""
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds; name the file
        raise FileFormatError(path, f"cannot read mesh: {exc}") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise FileFormatError(path, "mesh is empty (no triangles)")
    vertices = np.asarray(loaded.vertices, dtype=float)
    faces = np.asarray(loaded.faces, dtype=np.int64)
    if not np.all(np.isfinite(vertices)):
        raise FileFormatError(path, "mesh has NaN or infinite vertex coordinates")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise FileFormatError(path, "mesh has face indices outside its vertex list")
    return trimesh.Trimesh(vertices * np.asarray(scale, dtype=float), faces, process=False)


def shape_mesh(shape: LinkShape) -> trimesh.Trimesh:
    """The shape as a triangle mesh in the shape's own frame (not posed)."""
    if shape.kind == "box":
        return trimesh.creation.box(extents=shape.size)
    if shape.kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=2, radius=shape.radius)
    if shape.kind == "cylinder":
        return trimesh.creation.cylinder(radius=shape.radius, height=shape.length, sections=ROUND_SECTIONS)
    if shape.kind == "capsule":
        return trimesh.creation.capsule(height=shape.length, radius=shape.radius, count=[ROUND_SECTIONS, ROUND_SECTIONS])
    return load_mesh_file(shape.mesh_path, shape.scale)


def posed_shape_mesh(shape: LinkShape) -> trimesh.Trimesh:
    """The shape as a mesh in its link's frame (``link_T_shape`` applied)."""
    mesh = shape_mesh(shape).copy()
    mesh.apply_transform(shape.link_T_shape)
    return mesh


def link_meshes(shapes: tuple[LinkShape, ...]) -> trimesh.Trimesh | None:
    """All shapes of one link merged into one mesh in the link frame, or None if it has none."""
    if not shapes:
        return None
    return trimesh.util.concatenate([posed_shape_mesh(s) for s in shapes])
