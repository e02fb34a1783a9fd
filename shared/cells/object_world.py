"""Where a cell's movable objects are and which one a gripper holds: one model for the virtual
world the operator edits and for the remote world the robot reports.

Objects start at their cell pose. A grasp fixes the held object to the tool point (``tcp_T_held``)
so it rides with the arm; a release (or an insertion) leaves it where the tool put it. Task
calls name the object case-insensitively (``GRASP(peg)``): ``apply_task`` reads grasp*,
release* and insert* tasks (thesis §4.3.4's task vocabulary), the way the telerobot does.

Seated objects: an object that stands in a feature the way it stood at load (the peg on the floor
of HOLE1) touches its support by design. :func:`seated_feature` says where an object pose is
seated so, and the collision checks leave its resting contacts out (``shared.collision.cell_check``):
a peg inserted in HOLE2 is not a collision with the plate the operator must see.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from shared.spatial import invert

SEAT_LATERAL_M = 0.002
"""How far (m) across a feature's axis an object may stand from its seat and still be seated."""
SEAT_AXIAL_M = 0.003
"""How far (m) along the feature's axis (deeper or higher) an object may stand from its seat."""
SEAT_TILT_COS = float(np.cos(np.radians(5.0)))
"""The object's axes may tilt at most 5 deg from how it stood at load (cosine of that)."""


def _load_seat(cell, name: str):
    """The feature an object stands in at load (the nearest to its origin) and where it stands
    in that feature's frame, or None when the cell has no features."""
    if not cell.features:
        return None
    world_T_obj = np.asarray(cell.object(name).world_T_object, dtype=float)
    feature = min(cell.features.values(), key=lambda f: float(np.linalg.norm(f.world_T_feature[:3, 3] - world_T_obj[:3, 3])))
    return feature.name, invert(np.asarray(feature.world_T_feature, dtype=float)) @ world_T_obj


def seated_feature(cell, name: str, world_T_object: np.ndarray) -> str | None:
    """The feature in which ``name`` at ``world_T_object`` stands as it stood in its own at load
    (same offset along and across the feature's axis within ``SEAT_*``, not tilted), or None. A
    square peg turned about the hole's axis is still seated: only the axis is compared."""
    if name not in cell.object_names:
        return None
    seat = _load_seat(cell, name)
    if seat is None:
        return None
    _, feature_T_obj = seat
    pose = np.asarray(world_T_object, dtype=float)
    for feature in cell.features.values():
        world_T_f = np.asarray(feature.world_T_feature, dtype=float)
        here = invert(world_T_f) @ pose
        offset = here[:3, 3] - feature_T_obj[:3, 3]
        if abs(offset[2]) > SEAT_AXIAL_M or float(np.hypot(offset[0], offset[1])) > SEAT_LATERAL_M:
            continue
        if float(np.dot(here[:3, 2], feature_T_obj[:3, 2])) >= SEAT_TILT_COS:
            return feature.name
    return None


class ObjectWorld:
    """Object poses (world) and the held object of one side (virtual or remote)."""

    def __init__(self, cell) -> None:
        self.cell = cell
        self.placed: dict[str, np.ndarray] = {}
        """world_T_object of objects moved from their cell pose and not held."""
        self.held: str | None = None
        self.tcp_T_held: np.ndarray | None = None
        self.world_T_tcp_inserted: np.ndarray | None = None
        """Where an insertion's contract leaves the tool (the held object seated), until the
        gripper lets go: the arm's own end pose after a force-guided task only the robot knows."""

    # -- reading -----------------------------------------------------------------------------
    def resolve(self, name: str) -> str | None:
        """The cell's spelling of an object name, or None when the cell has no such object."""
        for n in self.cell.object_names:
            if n.lower() == name.lower():
                return n
        return None

    def world_T_object(self, name: str, world_T_tcp: np.ndarray | None = None) -> np.ndarray:
        """Where ``name`` is: riding with the tool at ``world_T_tcp`` when held (and the tool pose
        is given), else where it was left, else its cell pose."""
        if name == self.held and self.tcp_T_held is not None and world_T_tcp is not None:
            return self.tool_pose(world_T_tcp) @ self.tcp_T_held
        if name in self.placed:
            return self.placed[name]
        return np.asarray(self.cell.object(name).world_T_object, dtype=float)

    def poses(self, world_T_tcp: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Every moved object's pose, the held one at ``world_T_tcp`` (when given)."""
        out = dict(self.placed)
        if self.held is not None and self.tcp_T_held is not None and world_T_tcp is not None:
            out[self.held] = self.tool_pose(world_T_tcp) @ self.tcp_T_held
        return out

    def tool_pose(self, world_T_tcp: np.ndarray) -> np.ndarray:
        """The tool centre point as this world has it: where an insertion left it while the
        gripper still holds the seated object, else ``world_T_tcp`` (the arm's)."""
        return self.world_T_tcp_inserted if self.world_T_tcp_inserted is not None else world_T_tcp

    # -- changing ----------------------------------------------------------------------------
    def grasp(self, name: str, world_T_tcp: np.ndarray) -> None:
        """Hold ``name`` where it is now, fixed to the tool at ``world_T_tcp``."""
        here = self.world_T_object(name, world_T_tcp)
        self.placed.pop(name, None)
        self.world_T_tcp_inserted = None
        self.held, self.tcp_T_held = name, invert(world_T_tcp) @ here

    def release(self, world_T_tcp: np.ndarray) -> None:
        """Leave the held object where the tool at ``world_T_tcp`` puts it."""
        if self.held is not None and self.tcp_T_held is not None:
            self.placed[self.held] = self.tool_pose(world_T_tcp) @ self.tcp_T_held
        self.held, self.tcp_T_held = None, None
        self.world_T_tcp_inserted = None

    def place(self, name: str, world_T_object: np.ndarray) -> None:
        """Put a free object at a pose (a correction from a camera, say)."""
        self.placed[name] = np.array(world_T_object, dtype=float)

    def apply_task(self, task: str, args: tuple[str, ...] | list[str], world_T_tcp: np.ndarray) -> bool:
        """What a finished task does to the objects, with the tool at ``world_T_tcp``: grasp*
        holds its first argument, release* lets go where the tool is, insert* seats the held object
        in the feature named second (still held) or, with no such feature, lets go. True when
        something changed."""
        name = task.lower()
        if name.startswith("grasp") and args:
            obj = self.resolve(args[0])
            if obj is None:
                return False
            self.grasp(obj, world_T_tcp)
            return True
        if name.startswith("insert") and self.held is not None:
            if len(args) > 1 and self._seat(self.held, args[1], world_T_tcp):
                return True
            self.release(world_T_tcp)
            return True
        if name.startswith("release") and self.held is not None:
            self.release(world_T_tcp)
            return True
        return False

    def _seat(self, name: str, feature: str, world_T_tcp: np.ndarray) -> bool:
        """An insertion's contract: the robot searches and seats the held object, so it ends in
        ``feature`` the way it stood in its own feature at load (the peg on the hole's floor),
        still in the gripper (a release lets go), and the tool where that grip puts it
        (``world_T_tcp_inserted``). False (nothing changed) for an object with no seat at load
        or a feature the cell lacks."""
        hole = next((f for f in self.cell.features.values() if f.name.lower() == feature.lower()), None)
        seat = _load_seat(self.cell, name)
        if hole is None or seat is None or self.tcp_T_held is None:
            return False
        world_T_seated = np.asarray(hole.world_T_feature, dtype=float) @ seat[1]
        self.world_T_tcp_inserted = world_T_seated @ invert(self.tcp_T_held)
        return True

    def take_reported(self, world_T_objects: Mapping[str, np.ndarray], held: str | None, world_T_tcp: np.ndarray) -> None:
        """Take objects where a robot reports them: their poses, and the one it holds (fixed to
        its tool at ``world_T_tcp``). Names the cell does not have are ignored."""
        known = set(self.cell.object_names)
        poses = {k: np.array(v, dtype=float) for k, v in world_T_objects.items() if k in known}
        self.placed.update(poses)
        self.held, self.tcp_T_held = None, None
        self.world_T_tcp_inserted = None
        if held is not None and held in poses:
            self.held, self.tcp_T_held = held, invert(world_T_tcp) @ poses[held]
            self.placed.pop(held, None)

    def copy(self) -> ObjectWorld:
        """A world of its own with the same placed objects, held object and grip."""
        out = ObjectWorld(self.cell)
        out.placed = {k: v.copy() for k, v in self.placed.items()}
        out.held = self.held
        out.tcp_T_held = None if self.tcp_T_held is None else self.tcp_T_held.copy()
        out.world_T_tcp_inserted = None if self.world_T_tcp_inserted is None else self.world_T_tcp_inserted.copy()
        return out

    def take(self, other: ObjectWorld, world_T_tcp_self: np.ndarray) -> None:
        """Become ``other`` (a re-sync): its placed objects, its held object and grip. What this
        side held and the other does not stays where this side's tool holds it now."""
        if self.held is not None and self.tcp_T_held is not None:
            self.placed[self.held] = self.tool_pose(world_T_tcp_self) @ self.tcp_T_held
        self.placed.update({k: v.copy() for k, v in other.placed.items()})
        self.held = other.held
        self.tcp_T_held = None if other.tcp_T_held is None else other.tcp_T_held.copy()
        self.world_T_tcp_inserted = None if other.world_T_tcp_inserted is None else other.world_T_tcp_inserted.copy()
        if self.held is not None:
            self.placed.pop(self.held, None)

    def divergence(self, expected: ObjectWorld) -> tuple[str | None, float]:
        """The reported object (this side's) furthest from where ``expected`` has it: its name and
        the distance between the origins (m); (name, inf) when one side holds an object and the
        other does not (or another one); (None, 0) when all agree."""
        if self.held != expected.held:
            return self.held or expected.held, float("inf")
        worst, name = 0.0, None
        for obj, world_T in self.placed.items():
            if obj == expected.held:
                continue
            d = float(np.linalg.norm(world_T[:3, 3] - expected.world_T_object(obj)[:3, 3]))
            if d > worst:
                worst, name = d, obj
        return name, worst
