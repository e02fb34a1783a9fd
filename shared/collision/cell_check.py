"""One collision report for a whole cell: the scene's bodies (``SceneModel``) and, in a rover
cell, the ground (``shared.terrain.ground``), merged into one answer for an arm pose.

``CellCollision.check`` is the full answer the console shows after every move of the virtual arm
(touching pairs and their triangles, the nearest pair, the control zone and who sets it);
``CellCollision.touching`` is the cheap answer a plan's samples need (touching pairs only).
A held object rides with the gripper: it counts as tool, and its contact with the gripper's link
is not a collision. An object moved and set down seated in a feature as it stood at load (the peg
inserted in HOLE2, ``shared.cells.object_world.seated_feature``) keeps its resting contacts out of
the check, as it had them out at load: touching its support there is by design, not a collision.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from shared.cells.object_world import seated_feature
from shared.collision.scene import CollisionReport, SceneData, SceneModel
from shared.collision.zones import Zone, zone

_ZONE_RANK: dict[str, int] = {"free": 0, "quasi": 1, "operation": 2}


@dataclass(frozen=True)
class CellReport:
    """The arm at one pose against everything in the cell.

    ``pairs``: touching bodies (the ground is named ``GroundChecker.NAME``); ``triangles``: per
    body, the ids of its triangles that interfere (scene bodies only); ``min_distance`` and
    ``nearest``: the smallest distance (m) from the tool (the last link, or the object it holds)
    to an object or the ground, and that pair, the tool first (``None`` in a cell with nothing
    but the arm: the arm's own links are never the nearest, the operator asks what the tool is
    about to meet); ``zone`` with the object that sets it and that object's distance to the tool
    (m; ``None`` when no object counts)."""

    colliding: bool
    pairs: tuple[tuple[str, str], ...]
    triangles: dict[str, np.ndarray]
    min_distance: float | None
    nearest: tuple[str, str] | None
    zone: Zone
    zone_object: str | None
    zone_distance: float | None
    scene: CollisionReport
    ground: object | None = None
    """The ground's ``GroundContact`` in a rover cell, else ``None``."""


class CellCollision:
    """The cell's collision scene plus, where the cell has one, its ground."""

    def __init__(self, cell, scene: SceneModel | None = None, ground=None) -> None:
        """``scene``: the cell's collision model when the caller already built it (immutable;
        seconds to build), else built here without the ground; ``ground``: a
        ``GroundChecker`` (``None``: the cell has no terrain)."""
        self.cell = cell
        self.ground = ground
        exclude = (ground.NAME,) if ground is not None else ()
        self.scene = scene if scene is not None else SceneModel.from_cell(cell, exclude=exclude)
        self.tool_body = f"link{cell.robot.dof}"
        self._links = frozenset(b.name for b in self.scene.bodies if b.kind == "link")
        self._not_self: dict[str | None, np.ndarray] = {}  # per held object: the pairs "Nearest" may name

    def new_data(self) -> SceneData:
        return self.scene.new_data()

    def _skip(self, held: str | None, object_poses: Mapping[str, np.ndarray] | None = None) -> list[tuple[str, str]]:
        """Pairs left out: the held object and the gripper's link, and the resting contacts of
        every moved object that stands seated in a feature, held or not (the gripper still on
        the peg it seated; see the module docstring)."""
        skip = [(held, self.tool_body)] if held else []
        for name, world_T in (object_poses or {}).items():
            if not any(name in pair for pair in self.scene.resting_pairs):
                continue
            if seated_feature(self.cell, name, world_T) is not None:
                skip += [tuple(sorted(pair)) for pair in self.scene.resting_pairs if name in pair]
        return skip

    def check(self, q: np.ndarray, *, object_poses: Mapping[str, np.ndarray] | None = None, held: str | None = None,
              data: SceneData | None = None) -> CellReport:
        """Everything at ``q``: touching pairs with triangles, distances from the tool (and the
        held object) to the rest, and the zone (the most restrictive of the objects' and the
        ground's; at equal rank the nearer one sets it)."""
        poses = dict(object_poses) if object_poses else None
        tools = [self.tool_body, *([held] if held else [])]
        report = self.scene.check(q, object_poses=poses, distances=tools, skip=self._skip(held, poses), data=data)
        zs = zone(self.scene, self.cell, q, held=[held] if held else (), object_poses=poses, report=report)
        bodies = {n for p in report.pairs for n in (p.a, p.b)}
        colliding = report.colliding
        pairs = [(p.a, p.b) for p in report.pairs]
        min_distance, nearest_pair = self._nearest(report, tools, held)
        zone_now, zone_object, zone_distance = zs.zone, zs.object, zs.distance
        contact = None
        if self.ground is not None:
            contact = self.ground.contact(q)
            name = self.ground.NAME
            colliding = colliding or bool(contact.touching_links)
            pairs += [(link, name) for link in contact.touching_links]
            if min_distance is None or contact.distance < min_distance:
                min_distance, nearest_pair = contact.distance, (self.tool_body, name)
            if _ZONE_RANK[contact.zone] > _ZONE_RANK[zone_now] or (
                _ZONE_RANK[contact.zone] == _ZONE_RANK[zone_now] and contact.head_distance < zone_distance
            ):
                zone_now, zone_object, zone_distance = contact.zone, name, max(contact.head_distance, 0.0)
        return CellReport(
            colliding=bool(colliding), pairs=tuple(pairs),
            triangles={b: report.interfering_triangles(b) for b in bodies},
            min_distance=min_distance, nearest=nearest_pair, zone=zone_now, zone_object=zone_object,
            zone_distance=float(zone_distance) if np.isfinite(zone_distance) else None, scene=report, ground=contact,
        )

    def _not_self_pairs(self, held: str | None) -> np.ndarray:
        """Per pair of the scene: not a distance of the arm to itself (two of its links, or a
        link and the object it holds)."""
        keep = self._not_self.get(held)
        if keep is None:
            arm = self._links | ({held} if held else set())
            keep = self._not_self[held] = np.array([not (a in arm and b in arm) for a, b in self.scene.pair_names], dtype=bool)
        return keep

    def _nearest(self, report: CollisionReport, tools: list[str], held: str | None) -> tuple[float | None, tuple[str, str] | None]:
        """The tool's nearest object (the arm itself never counts), tool body first."""
        nearest = report.nearest_among(self._not_self_pairs(held))
        if nearest is None:
            return None, None
        a, b = (nearest.a, nearest.b) if nearest.a in tools else (nearest.b, nearest.a)
        return nearest.distance, (a, b)

    def touching(self, q: np.ndarray, *, object_poses: Mapping[str, np.ndarray] | None = None, held: str | None = None,
                 data: SceneData | None = None, triangles: bool = False) -> tuple[tuple[tuple[str, str], ...], CollisionReport]:
        """The touching pairs at ``q`` (scene and ground), without distances, and the scene's
        report (for its triangles when ``triangles``)."""
        poses = dict(object_poses) if object_poses else None
        report = self.scene.check(q, object_poses=poses, distances="none",
                                  skip=self._skip(held, poses), triangles=triangles, data=data)
        pairs = [(p.a, p.b) for p in report.pairs]
        if self.ground is not None:
            pairs += [(link, self.ground.NAME) for link in self.ground.touches(q)]
        return tuple(pairs), report

    def involves_arm(self, bodies: Iterable[str] | None, held: str | None = None) -> bool:
        """Whether a touching pair is the arm's doing: one of its bodies is a link (the ground's
        pairs name one too), and the held object is not in it (it rides with the gripper, which a
        plan does not model). Two objects touching each other are not the motion's doing."""
        if bodies is None:
            return False
        bodies = tuple(bodies)
        if held is not None and held in bodies:
            return False
        return any(b in self._links for b in bodies)
