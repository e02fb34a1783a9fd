"""The terrain of a cell: the object named ``terrain`` whose shape is a triangle mesh (PLY),
posed into the world, turned into the tree and a checker for the cell's robot."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.cells.cell import Cell
from shared.errors import InputError
from shared.terrain.arm import ArmModel, arm_model
from shared.terrain.checks import TerrainChecker
from shared.terrain.cloud import read_ply
from shared.terrain.tree import TerrainTree, build_tree
from shared.terrain.triangulate import TerrainMesh

TERRAIN_OBJECT = "terrain"


@dataclass(frozen=True)
class CellTerrain:
    mesh: TerrainMesh
    tree: TerrainTree
    arm: ArmModel
    checker: TerrainChecker


def has_terrain(cell: Cell) -> bool:
    """Whether the cell carries a terrain mesh (an object named ``terrain`` with a mesh shape)."""
    return any(o.name == TERRAIN_OBJECT and any(s.kind == "mesh" for s in o.shapes) for o in cell.objects)


def cell_terrain_mesh(cell: Cell) -> TerrainMesh:
    """The cell's terrain mesh in world coordinates: every mesh shape of the ``terrain`` object
    (a ground and a stone on it, say), posed and joined into one triangle set."""
    obj = next((o for o in cell.objects if o.name == TERRAIN_OBJECT), None)
    if obj is None:
        raise InputError(f"cell {cell.name!r} has no object named {TERRAIN_OBJECT!r}")
    shapes = [s for s in obj.shapes if s.kind == "mesh"]
    if not shapes:
        raise InputError(f"cell {cell.name!r}: object {TERRAIN_OBJECT!r} has no mesh shape")
    from pathlib import Path

    verts, tris, n = [], [], 0
    for shape in shapes:
        vertices, faces = read_ply(Path(shape.mesh_path))
        if faces is None or len(faces) == 0:
            raise InputError(f"{shape.mesh_path}: the terrain mesh has no triangles")
        world_T_mesh = obj.world_T_object @ shape.link_T_shape
        verts.append((vertices * np.asarray(shape.scale)) @ world_T_mesh[:3, :3].T + world_T_mesh[:3, 3])
        tris.append(np.asarray(faces, dtype=np.int64) + n)
        n += len(vertices)
    return TerrainMesh(np.ascontiguousarray(np.concatenate(verts)), np.ascontiguousarray(np.concatenate(tris), dtype=np.int32))


def load_cell_terrain(cell: Cell, n_sensors: int = 36) -> CellTerrain:
    """Mesh, tree, arm model and checker of a terrain cell (build once per cell)."""
    mesh = cell_terrain_mesh(cell)
    tree = build_tree(mesh)
    arm = arm_model(cell.robot, n_sensors)
    return CellTerrain(mesh, tree, arm, TerrainChecker(tree, arm, cell.world_T_base))
