"""Segmented composite control zones (thesis section 4.2.1) from exact tool-object distances.

The space around each object is split by its ``ZoneDistances`` (``cell.zone_distances(name)``):
distance > ``quasi``: free-motion zone; ``operation`` < distance <= ``quasi``: quasi-operation
zone; distance <= ``operation``: operation zone. The robot's zone is the most restrictive over
the objects, where an object's distance is the smallest distance from the tool bodies (the last
link, which carries the gripper, plus any held object) to it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from shared.cells.cell import ZoneDistances
from shared.collision.scene import CollisionReport, SceneData, SceneModel
from shared.errors import UnknownNameError

Zone = Literal["free", "quasi", "operation"]
_RANK = {"free": 0, "quasi": 1, "operation": 2}


def classify(distance: float, limits: ZoneDistances) -> Zone:
    """The zone of one distance (m) under one object's boundaries."""
    if distance <= limits.operation:
        return "operation"
    if distance <= limits.quasi:
        return "quasi"
    return "free"


@dataclass(frozen=True)
class ZoneState:
    """``zone``: the robot's zone; ``nearest``/``distance``: the object nearest the tool and its
    distance (m; 0 when touching; ``None``/inf without objects); ``object``: the object that
    sets the zone (the one with the most restrictive zone, nearest first); per object:
    ``distances`` and ``zones``."""

    zone: Zone
    nearest: str | None
    distance: float
    object: str | None
    distances: dict[str, float]
    zones: dict[str, Zone]


def tool_pairs(model: SceneModel, tool_bodies: Iterable[str], objects: Iterable[str]) -> list[tuple[str, str]]:
    pairs = []
    for t in tool_bodies:
        for o in objects:
            if o != t:
                pairs.append((t, o))
    return pairs


def zone(
    model: SceneModel,
    cell,
    q,
    *,
    tool_bodies: Iterable[str] | None = None,
    held: Iterable[str] = (),
    object_poses: Mapping[str, np.ndarray] | None = None,
    report: CollisionReport | None = None,
    data: SceneData | None = None,
) -> ZoneState:
    """Classify the control zone at ``q``.

    ``tool_bodies``: bodies that make up the tool (default: the robot's last link). ``held``:
    objects carried by the gripper (they count as tool, not as obstacles). ``report``: a report
    of ``model.check`` at the same pose that already holds these distances (else one is made).
    """
    held = tuple(held)
    tools = tuple(tool_bodies) if tool_bodies is not None else (f"link{cell.robot.dof}",)
    tools += held
    for name in tools:
        model.body(name)
    objects = [model.bodies[i].name for i in model.object_bodies if model.bodies[i].name not in held]
    pairs = [p for p in tool_pairs(model, tools, objects) if frozenset(p) in model._pair_index]
    if report is None:
        report = model.check(q, object_poses=object_poses, distances=pairs, data=data, triangles=False)
    per_object: dict[str, float] = {}
    for t, o in pairs:
        try:
            d = report.distance(t, o).distance
        except UnknownNameError:
            continue  # the pair was skipped in this check (e.g. a resting contact)
        per_object[o] = min(d, per_object.get(o, np.inf))
    zones = {o: classify(d, cell.zone_distances(o)) for o, d in per_object.items()}
    if not per_object:
        return ZoneState("free", None, float("inf"), None, {}, {})
    nearest = min(per_object, key=per_object.get)
    setter = max(per_object, key=lambda o: (_RANK[zones[o]], -per_object[o]))
    return ZoneState(zones[setter], nearest, per_object[nearest], setter, per_object, zones)
