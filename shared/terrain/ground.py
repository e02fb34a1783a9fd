"""The arm against a rover cell's ground (seed 004): contact, the head's distance and the control
zone the ground sets, picking a point on the terrain, and instrument placement.

Why a class of its own: a terrain has tens of thousands of triangles and its own multi-way AABB
tree and checker (``shared.terrain.checker``); the generic collision scene leaves it out (an OBB
hierarchy over it costs seconds to build and answers slower). ``shared.collision.cell_check``
merges what this says into the cell's collision report; the console draws it.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from shared.cells.cell import Cell
from shared.collision.zones import Zone, classify
from shared.errors import InputError
from shared.terrain.cell import (
    TERRAIN_OBJECT,
    CellTerrain,
    has_terrain,
    load_cell_terrain,
)
from shared.terrain.placement import (
    MAX_STANDOFF,
    SAFETY_MARGIN,
    PlacementResult,
    plan_placement,
    terrain_point_at,
)
from shared.terrain.tree import ray_hits

#: at most this many touching triangles are returned for drawing (the count is always exact)
MAX_DRAWN_CONTACTS = 2000
#: how far a picking ray may travel (m)
PICK_RANGE = 50.0


@dataclass(frozen=True)
class SensorReading:
    """The virtual sensors' segments (world, m) and which of them touch the ground."""

    starts: np.ndarray
    ends: np.ndarray
    collides: np.ndarray
    distance: float
    in_collision: bool


@dataclass(frozen=True)
class GroundContact:
    """The arm against the ground at one joint vector: the exact distance with its witness points,
    the head's (tool's) distance, the links touching, the zone the ground sets for the tool, the
    touching triangles' corners (at most ``MAX_DRAWN_CONTACTS``) and the sensors' reading."""

    distance: float
    head_distance: float
    touching_links: tuple[str, ...]
    zone: Zone
    in_collision: bool
    shape: str
    world_p_arm: np.ndarray
    world_p_terrain: np.ndarray
    contact_corners: np.ndarray
    sensors: SensorReading


class GroundChecker:
    """Checks and placement over one cell's terrain; thread-safe (the page and the API call it)."""

    NAME = TERRAIN_OBJECT

    def __init__(self, cell: Cell, n_sensors: int = 36) -> None:
        self.cell = cell
        self.terrain: CellTerrain = load_cell_terrain(cell, n_sensors)
        arm = self.terrain.checker.arm
        self._groups = np.zeros(len(arm.shapes), np.int64)
        self._groups[arm.tool_shape] = 1  # group 0: the arm without its head; group 1: the head
        self._shape_links = [f"link{s.link}" for s in arm.shapes]
        self._limits = cell.zone_distances(TERRAIN_OBJECT)
        self._lock = threading.Lock()

    @staticmethod
    def for_cell(cell: Cell) -> GroundChecker | None:
        """The checker of a terrain cell, ``None`` for any other cell."""
        return GroundChecker(cell) if has_terrain(cell) else None

    def contact(self, q: np.ndarray) -> GroundContact:
        """Exact distance (with witnesses), the head's distance, the sensors' reading and, on
        contact, the touching links and triangles, at joint vector ``q``."""
        q = np.asarray(q, dtype=float)
        checker = self.terrain.checker
        with self._lock:
            exact = checker.exact_check(q, per_shape=False)
            groups, *_ = checker.group_distances(q, self._groups, 2)
            sensors = checker.sensor_check(q)
            touching = self._touching_links(q) if exact.in_collision else ()
        mesh = self.terrain.mesh
        corners = mesh.vertices[mesh.faces[exact.contact_triangles[:MAX_DRAWN_CONTACTS]]] if exact.in_collision else np.zeros((0, 3, 3))
        head = float(groups[1])
        return GroundContact(
            distance=float(exact.distance), head_distance=head, touching_links=touching,
            zone=classify(max(head, 0.0), self._limits), in_collision=bool(exact.in_collision), shape=str(exact.shape),
            world_p_arm=np.asarray(exact.world_p_arm, dtype=float), world_p_terrain=np.asarray(exact.world_p_terrain, dtype=float),
            contact_corners=corners,
            sensors=SensorReading(np.asarray(sensors.A), np.asarray(sensors.B), np.asarray(sensors.collides),
                                  float(sensors.distance), bool(sensors.in_collision)),
        )

    def touches(self, q: np.ndarray) -> tuple[str, ...]:
        """The links touching the ground at ``q`` (empty when clear): the cheap check a plan's
        samples need."""
        q = np.asarray(q, dtype=float)
        with self._lock:
            if self.terrain.checker.min_distance(q) > 0.0:
                return ()
            return self._touching_links(q)

    def _touching_links(self, q: np.ndarray) -> tuple[str, ...]:
        n = len(self._shape_links)
        per_shape, *_ = self.terrain.checker.group_distances(q, np.arange(n), n)
        return tuple(sorted({self._shape_links[i] for i, d in enumerate(per_shape) if d <= 0.0}))

    def pick(self, world_p_origin: np.ndarray, world_d: np.ndarray) -> np.ndarray:
        """The first terrain point along a ray (a click in the 3D view); ``InputError`` if the
        ray misses the ground."""
        o = np.asarray(world_p_origin, dtype=float).reshape(3)
        d = np.asarray(world_d, dtype=float).reshape(3)
        norm = float(np.linalg.norm(d))
        if not (np.all(np.isfinite(o)) and np.isfinite(norm) and norm > 0.0):
            raise InputError("a picking ray needs a finite origin and a non-zero direction")
        t = np.empty(1)
        pos = np.empty(1, np.int64)
        ray_hits(o[None], (d / norm)[None], PICK_RANGE, *self.terrain.tree.arrays(), t, pos)
        if pos[0] < 0:
            raise InputError("the picked point is not on the terrain (the ray misses the ground)")
        return o + (d / norm) * float(t[0])

    def ground_point(self, x: float, y: float) -> np.ndarray:
        """The terrain point at ground position (x, y) (world, m)."""
        return terrain_point_at(self.terrain.checker, float(x), float(y))

    def place(self, world_p_target: np.ndarray, *, max_standoff: float = MAX_STANDOFF, margin: float = SAFETY_MARGIN) -> PlacementResult:
        """Plan the instrument placement at a terrain point (``shared.terrain.placement``)."""
        with self._lock:
            return plan_placement(self.terrain.checker, np.asarray(world_p_target, dtype=float), max_standoff=max_standoff, margin=margin)
