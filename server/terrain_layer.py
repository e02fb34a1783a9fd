"""The terrain of a rover cell in the console session (seed 004): arm-to-ground checks of the
virtual arm, the virtual sensors on demand, and instrument placement at a picked point.

Why a layer of its own: a terrain has tens of thousands of triangles and its own multi-way AABB
tree and checker (``shared.terrain``); the generic collision scene leaves it out (building an OBB
hierarchy over it costs seconds and answers slower). The session asks this layer after every
change of the virtual arm and merges the answer into its collision view and control zone; the
page draws what :class:`TerrainView` says. All geometry is computed by ``shared.terrain``.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

import numpy as np

from server.console_models import PlacementCandidateView, PlacementView, TerrainSensorsView, TerrainView
from shared.cells.cell import Cell
from shared.collision.zones import Zone, classify
from shared.errors import InputError
from shared.language.formatter import format_statement
from shared.language.statements import Statement
from shared.terrain.cell import TERRAIN_OBJECT, CellTerrain, has_terrain, load_cell_terrain
from shared.terrain.placement import MAX_STANDOFF, SAFETY_MARGIN, PlacementResult, plan_placement, terrain_point_at
from shared.terrain.tree import ray_hits

log = logging.getLogger(__name__)

#: at most this many touching triangles are sent to the page (the count is always exact)
MAX_DRAWN_CONTACTS = 2000
#: how far a picking ray may travel (m)
PICK_RANGE = 50.0


@dataclass(frozen=True)
class TerrainContact:
    """What the session's collision view needs: the links touching the ground, the overall and
    the head's distances, and the control zone the ground sets for the tool."""

    distance: float
    head_distance: float
    touching_links: tuple[str, ...]
    zone: Zone


class TerrainLayer:
    """Checks and placement over one cell's terrain; thread-safe (the page and the API call it)."""

    NAME = TERRAIN_OBJECT

    def __init__(self, cell: Cell, n_sensors: int = 36) -> None:
        self.cell = cell
        self.terrain: CellTerrain = load_cell_terrain(cell, n_sensors)
        checker = self.terrain.checker
        arm = checker.arm
        self._groups = np.zeros(len(arm.shapes), np.int64)
        self._groups[arm.tool_shape] = 1  # group 0: the arm without its head; group 1: the head
        self._shape_links = [f"link{s.link}" for s in arm.shapes]
        self._limits = cell.zone_distances(TERRAIN_OBJECT)
        self._lock = threading.Lock()
        self.show_sensors = False
        self._placement: tuple[PlacementResult, PlacementView] | None = None

    @staticmethod
    def for_cell(cell: Cell) -> TerrainLayer | None:
        """The layer of a terrain cell, ``None`` for any other cell."""
        return TerrainLayer(cell) if has_terrain(cell) else None

    # -- the arm against the ground --------------------------------------------------------
    def evaluate(self, q: np.ndarray) -> tuple[TerrainContact, TerrainView]:
        """Exact distance (with witnesses), the head's distance, the sensors' reading and, on
        contact, the touching triangles, at joint vector ``q``."""
        q = np.asarray(q, dtype=float)
        checker = self.terrain.checker
        with self._lock:
            exact = checker.exact_check(q, per_shape=False)
            groups, *_ = checker.group_distances(q, self._groups, 2)
            sensors = checker.sensor_check(q)
            show = self.show_sensors
        touching: tuple[str, ...] = ()
        corners: list = []
        if exact.in_collision:
            per_shape, *_ = checker.group_distances(q, np.arange(len(self._shape_links)), len(self._shape_links))
            touching = tuple(sorted({self._shape_links[i] for i, d in enumerate(per_shape) if d <= 0.0}))
            faces = exact.contact_triangles[:MAX_DRAWN_CONTACTS]
            mesh = self.terrain.mesh
            corners = mesh.vertices[mesh.faces[faces]].tolist()
        head = float(groups[1])
        contact = TerrainContact(float(exact.distance), head, touching, classify(max(head, 0.0), self._limits))
        sensor_distance = sensors.distance
        view = TerrainView(
            distance=float(exact.distance), in_collision=exact.in_collision, shape=exact.shape,
            world_p_arm=exact.world_p_arm.tolist(), world_p_terrain=exact.world_p_terrain.tolist(), head_distance=head,
            sensor_distance=sensor_distance if np.isfinite(sensor_distance) else None,
            sensor_collision=sensors.in_collision, contact_corners=corners,
            sensors=TerrainSensorsView(starts=sensors.A.tolist(), ends=sensors.B.tolist(), collides=sensors.collides.tolist())
            if show else None,
        )
        return contact, view

    def touches(self, q: np.ndarray) -> tuple[str, ...]:
        """The links touching the ground at ``q`` (empty when clear): the preview's check."""
        checker = self.terrain.checker
        with self._lock:
            if checker.min_distance(np.asarray(q, dtype=float)) > 0.0:
                return ()
            per_shape, *_ = checker.group_distances(q, np.arange(len(self._shape_links)), len(self._shape_links))
        return tuple(sorted({self._shape_links[i] for i, d in enumerate(per_shape) if d <= 0.0}))

    # -- picking and placement -------------------------------------------------------------
    def pick(self, world_p_origin: np.ndarray, world_d: np.ndarray) -> np.ndarray:
        """The first terrain point along a ray (a click in the 3D view); ``InputError`` if the
        ray misses the ground."""
        o = np.asarray(world_p_origin, dtype=float).reshape(3)
        d = np.asarray(world_d, dtype=float).reshape(3)
        norm = float(np.linalg.norm(d))
        if not (np.all(np.isfinite(o)) and np.isfinite(norm) and norm > 0.0):
            raise InputError("a picking ray needs a finite origin and a non-zero direction")
        tree = self.terrain.tree
        t = np.empty(1)
        pos = np.empty(1, np.int64)
        ray_hits(o[None], (d / norm)[None], PICK_RANGE, *tree.arrays(), t, pos)
        if pos[0] < 0:
            raise InputError("the picked point is not on the terrain (the ray misses the ground)")
        return o + (d / norm) * float(t[0])

    def ground_point(self, x: float, y: float) -> np.ndarray:
        """The terrain point at ground position (x, y) (world, m)."""
        return terrain_point_at(self.terrain.checker, float(x), float(y))

    def place(self, world_p_target: np.ndarray, *, max_standoff: float = MAX_STANDOFF, margin: float = SAFETY_MARGIN) -> PlacementView:
        """Plan the instrument placement at a terrain point; the view is kept as the current one."""
        with self._lock:
            result = plan_placement(self.terrain.checker, np.asarray(world_p_target, dtype=float),
                                    max_standoff=max_standoff, margin=margin)
        view = placement_view(result)
        with self._lock:
            self._placement = (result, view)
        log.info("placement at %s mm: %d configurations", np.round(result.world_p_target * 1e3, 1).tolist(),
                 len(result.candidates))
        return view

    @property
    def placement(self) -> PlacementView | None:
        with self._lock:
            return self._placement[1] if self._placement is not None else None

    def placement_program(self) -> tuple[Statement, ...]:
        """The statements of the current placement; ``InputError`` when there is none."""
        with self._lock:
            current = self._placement
        if current is None:
            raise InputError("no placement yet: pick a target on the terrain first")
        if not current[0].program:
            raise InputError(f"the placement at the picked target has no safe configuration ({current[1].message})")
        return tuple(current[0].program)

    def candidate_q(self, index: int) -> np.ndarray:
        """Joint vector of candidate ``index`` (0 = the best) of the current placement."""
        with self._lock:
            current = self._placement
        if current is None:
            raise InputError("no placement yet: pick a target on the terrain first")
        candidates = current[0].candidates
        if not 0 <= index < len(candidates):
            raise InputError(f"placement candidate {index + 1} does not exist: there are {len(candidates)}")
        return candidates[index].q.copy()

    def clear_placement(self) -> None:
        with self._lock:
            self._placement = None


def placement_view(result: PlacementResult) -> PlacementView:
    """The typed view of a placement result, with the program as statement text."""
    candidates = [
        PlacementCandidateView(
            q=c.q.tolist(), q_deg=np.degrees(c.q).tolist(), standoff=c.standoff, clearance=c.clearance,
            head_clearance=c.head_clearance, tilt_deg=float(np.degrees(c.tilt)), approach=c.q_approach is not None,
        )
        for c in result.candidates
    ]
    if candidates:
        best = candidates[0]
        message = (f"{len(candidates)} safe configuration(s); best: standoff {best.standoff * 1e3:.1f} mm, "
                   f"arm clearance {best.clearance * 1e3:.1f} mm, tilt {best.tilt_deg:.1f} deg")
    else:
        why = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in result.rejected.items() if v)
        message = f"no safe configuration ({why or 'no IK solution'})"
    return PlacementView(
        world_p_target=result.world_p_target.tolist(), world_n_surface=result.world_n_surface.tolist(),
        candidates=candidates, rejected=dict(result.rejected), program=[format_statement(s) for s in result.program],
        message=message,
    )
