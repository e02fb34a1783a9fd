"""Collision core (seed 002): hybrid bounding-volume hierarchies, exact triangle tests,
exact distances, for the robot at q among a cell's objects. See ``scene.SceneModel``; bodies
made of closed convex shapes get their distances by GJK on certified pieces (``convex``,
``gjk``), the others by the triangle descent (``kernels``).
Mechanical interference zones in joint space (seed 001): ``interference``."""

from shared.collision.interference import (
    InterferenceZones,
    PathCheck,
    PathDetour,
    PathOk,
    PathRefused,
    PolygonZone,
    PolyhedronZone,
    robot_zones,
)
from shared.collision.mesh_model import BodyMesh, MeshError, body_mesh, body_mesh_from_arrays
from shared.collision.obb_tree import OBBTree, build_obb_tree, fit_obb
from shared.collision.scene import CollisionReport, InterferingPair, PairDistance, SceneData, SceneModel
from shared.collision.zones import ZoneState, classify, zone

__all__ = [
    "BodyMesh", "MeshError", "body_mesh", "body_mesh_from_arrays", "OBBTree", "build_obb_tree", "fit_obb",
    "CollisionReport", "InterferingPair", "PairDistance", "SceneData", "SceneModel",
    "ZoneState", "classify", "zone",
    "InterferenceZones", "PathCheck", "PathDetour", "PathOk", "PathRefused", "PolygonZone", "PolyhedronZone",
    "robot_zones",
]
