"""Validated triangle soups, one per rigid body (a robot link or a cell object).

A body's mesh is its shapes' meshes merged in the body frame in the same order as
``shared.robots.shapes.link_meshes`` (so triangle ids match the meshes the UI draws). Each
shape is checked first and a bad one is refused with an error naming the body, the shape and
the mesh file: no triangles, NaN or infinite vertices, face indices out of range, only
zero-area triangles, or non-manifold edges (an edge shared by more than two triangles: the mesh
is not a surface and intersection results would not mean contact).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from shared.errors import FileFormatError
from shared.robots.description import LinkShape
from shared.robots.shapes import posed_shape_mesh


class MeshError(FileFormatError):
    """A body's mesh cannot be used for collision checking (names the file or the shape)."""


@dataclass(frozen=True)
class BodyMesh:
    """A body's triangles in its own frame: ``vertices`` (V, 3) m, ``faces`` (F, 3) indices.

    Triangle id ``k`` is row ``k`` of ``faces``: the id reported for interfering triangles.
    ``shape_faces``: the ``[lo, hi)`` range of ``faces`` each of the body's shapes contributed,
    in order (one range for a body made from raw arrays): the candidate convex pieces.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    n_degenerate: int = 0
    shape_faces: tuple[tuple[int, int], ...] = ()

    @property
    def triangles(self) -> np.ndarray:
        """(F, 3, 3) vertex coordinates per triangle."""
        return self.vertices[self.faces]

    def to_trimesh(self) -> trimesh.Trimesh:
        return trimesh.Trimesh(self.vertices, self.faces, process=False)


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


def check_triangles(vertices: np.ndarray, faces: np.ndarray, source: str, require_manifold: bool = True) -> int:
    """Raise ``MeshError`` naming ``source`` if the soup cannot be used; return the number of
    zero-area triangles (kept: they are tested as segments)."""
    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise MeshError(source, "mesh is empty (no triangles)")
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        raise MeshError(source, "mesh has no vertices")
    if not np.all(np.isfinite(vertices)):
        bad = int(np.argwhere(~np.all(np.isfinite(vertices), axis=1))[0, 0])
        raise MeshError(source, f"vertex {bad} has a NaN or infinite coordinate")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError(source, f"face indices must lie in [0, {len(vertices) - 1}]")
    tri = vertices[faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    extent = float(np.ptp(vertices, axis=0).max())
    degenerate = area2 <= 1e-12 * max(extent, 1e-300) ** 2
    if degenerate.all():
        raise MeshError(source, "every triangle has zero area")
    if require_manifold:
        edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        edges = edges[edges[:, 0] != edges[:, 1]]
        _, counts = np.unique(edges, axis=0, return_counts=True)
        if counts.size and counts.max() > 2:
            raise MeshError(source, f"mesh is not manifold: {int((counts > 2).sum())} edges are shared by more than two triangles")
    return int(degenerate.sum())


def _shape_source(body: str, index: int, shape: LinkShape) -> str:
    if shape.kind == "mesh":
        return shape.mesh_path
    return f"{body} shape {index} ({shape.kind})"


def body_mesh(name: str, shapes: Sequence[LinkShape]) -> BodyMesh | None:
    """Merge and check a body's shapes; ``None`` if it has no shapes."""
    if not shapes:
        return None
    vertices: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    offset = 0
    n_degenerate = 0
    ranges: list[tuple[int, int]] = []
    n_faces = 0
    for k, shape in enumerate(shapes):
        source = _shape_source(name, k, shape)
        mesh = posed_shape_mesh(shape)  # load_mesh_file already names the file on read errors
        v = np.asarray(mesh.vertices, dtype=float)
        f = np.asarray(mesh.faces, dtype=np.int64)
        n_degenerate += check_triangles(v, f, source)
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
        ranges.append((n_faces, n_faces + len(f)))
        n_faces += len(f)
    return BodyMesh(
        name, _readonly(np.concatenate(vertices)), _readonly(np.concatenate(faces)), n_degenerate, tuple(ranges)
    )


def body_mesh_from_arrays(name: str, vertices: np.ndarray, faces: np.ndarray, require_manifold: bool = True) -> BodyMesh:
    """A checked body from raw arrays (the name is used as the source in errors)."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces)
    if faces.size and not np.issubdtype(faces.dtype, np.integer):
        raise MeshError(name, "face indices must be integers")
    n_degenerate = check_triangles(vertices, faces, name, require_manifold)
    return BodyMesh(
        name, _readonly(vertices), _readonly(faces.astype(np.int64)), n_degenerate, ((0, len(faces)),)
    )
