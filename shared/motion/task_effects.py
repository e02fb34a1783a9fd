"""What a task does to the arm and the objects, as poses: the registry's ``TaskEffect``
(``shared.language.tasks``) turned into geometry, by the functions both sides call.

The robot's task code (``robot_sim.executor``) aims its motions at the pose :func:`arm_end`
names, from the grip its sensors give (where the peg really sits in the fingers); the console's
planner (``shared.motion.interpreter``) predicts the same pose from the grip its model gives
(:class:`TaskObjects`: where the objects stand and which one the gripper holds, changed by each
task's ``objects`` effect as the program is planned). So the preview, the virtual arm and the
robot end in the same place, to within what contact decides (the effect's tolerance).

* ``still``: the tool stays.
* ``lift``: the tool moves ``distance_m`` along the hole's axis (``extract_peg``).
* ``seat``: the held object's foot on the hole's axis, the seat depth below the mouth, the tool's
  orientation kept (``insert_peg``). The seat depth is how deep the object stood in its feature
  when the cell was loaded (the peg on HOLE1's floor: 30 mm), else ``HOLE_DEPTH_M``.
* ``retreat``: the tool backs ``distance_m`` along its own axis (``release``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from shared.language.statements import is_action, is_task
from shared.language.tasks import HOLE_DEPTH_M, TASKS, TaskEffect, resolve_name
from shared.spatial import invert

SEAT_REACH_M = 0.002
"""How far (m) from a feature's axis an object's foot may stand at load and count as in it."""
GRASP_REACH_M = 0.005
"""How far (m) beyond an object's reach from its origin to its foot the tool point may be for a
planned grasp to hold it: farther, the plan does not know what the fingers will close on."""


@dataclass(frozen=True)
class Grip:
    """An object in the gripper: where it sits in the tool frame, and its foot (the point the
    seat puts on the hole's floor) in its own frame."""

    name: str
    tcp_T_object: np.ndarray
    object_p_foot: np.ndarray

    @property
    def tcp_p_foot(self) -> np.ndarray:
        """The foot in the tool frame."""
        return self.tcp_T_object[:3, :3] @ self.object_p_foot + self.tcp_T_object[:3, 3]


@dataclass(frozen=True)
class TaskObjects:
    """The cell's movable objects as a plan has them: where the free ones stand (world), the
    grip (None: the gripper holds nothing the planner knows of), each object's foot and seat
    depth. Never changed in place: each task's effect gives a new one."""

    poses: Mapping[str, np.ndarray] = field(default_factory=dict)
    grip: Grip | None = None
    feet: Mapping[str, np.ndarray] = field(default_factory=dict)
    depths: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def of_cell(cls, cell) -> "TaskObjects":
        """The objects as the cell file places them, nothing held."""
        poses, feet, depths, grip = {}, {}, {}, None
        for obj in cell.objects:
            if not obj.movable:
                continue
            feet[obj.name] = object_foot(obj)
            if obj.held:  # it starts in the gripper, posed relative to the tool point
                grip = Grip(obj.name, np.asarray(obj.world_T_object, dtype=float), feet[obj.name])
                depths[obj.name] = HOLE_DEPTH_M
                continue
            poses[obj.name] = np.asarray(obj.world_T_object, dtype=float)
            depths[obj.name] = seat_depth(cell, obj.name, feet[obj.name])
        return cls(poses, grip, feet, depths)

    @classmethod
    def of_world(cls, cell, placed: Mapping[str, np.ndarray], held: str | None,
                 tcp_T_held: np.ndarray | None) -> "TaskObjects":
        """The objects as an object world has them (``shared.cells.object_world.ObjectWorld``:
        its ``placed``, ``held`` and ``tcp_T_held``)."""
        base = cls.of_cell(cell)
        poses = dict(base.poses)
        poses.update({k: np.asarray(v, dtype=float) for k, v in placed.items() if k in poses})
        grip = None
        if held is not None and tcp_T_held is not None and held in base.feet:
            poses.pop(held, None)
            grip = Grip(held, np.asarray(tcp_T_held, dtype=float), base.feet[held])
        return replace(base, poses=poses, grip=grip)

    def world_T_object(self, name: str, world_T_tcp: np.ndarray) -> np.ndarray | None:
        if self.grip is not None and self.grip.name == name:
            return world_T_tcp @ self.grip.tcp_T_object
        return self.poses.get(name)

    def after(self, effect: TaskEffect, args: tuple[str, ...], world_T_tcp: np.ndarray) -> "TaskObjects":
        """The objects after a task with this ``effect`` and ``args``, the tool at
        ``world_T_tcp`` when the gripper closed or opened (a carried object rides along)."""
        if effect.objects == "grasp" and args:
            name = resolve_name(args[0], tuple(self.feet))
            here = None if name is None else self.world_T_object(name, world_T_tcp)
            reach = GRASP_REACH_M + (0.0 if name is None else float(np.linalg.norm(self.feet[name])))
            if here is None or np.linalg.norm(here[:3, 3] - world_T_tcp[:3, 3]) > reach:
                # an object the planner does not know, or not where the tool closes: nothing it can carry
                return replace(self, grip=None)
            poses = {k: v for k, v in self.poses.items() if k != name}
            if self.grip is not None and self.grip.name != name:
                poses[self.grip.name] = world_T_tcp @ self.grip.tcp_T_object
            return replace(self, poses=poses, grip=Grip(name, invert(world_T_tcp) @ here, self.feet[name]))
        if effect.objects == "release" and self.grip is not None:
            poses = dict(self.poses)
            poses[self.grip.name] = world_T_tcp @ self.grip.tcp_T_object
            return replace(self, poses=poses, grip=None)
        return self


def object_foot(obj) -> np.ndarray:
    """The object's foot in its own frame: the lowest point of its first shape along its z axis
    (a box's bottom face centre), the origin for a shape without a known extent."""
    if not obj.shapes:
        return np.zeros(3)
    shape = obj.shapes[0]
    if shape.kind == "box":
        half = float(np.asarray(shape.size, dtype=float)[2]) / 2.0
    elif shape.kind in ("cylinder", "capsule"):
        half = shape.length / 2.0 + (shape.radius if shape.kind == "capsule" else 0.0)
    elif shape.kind == "sphere":
        half = shape.radius
    else:
        return np.zeros(3)
    T = np.asarray(shape.link_T_shape, dtype=float)
    return T[:3, 3] - half * T[:3, 2]


def seat_depth(cell, name: str, object_p_foot: np.ndarray | None = None) -> float:
    """How deep ``name``'s foot stood below the mouth of the feature it stood in at load (the
    peg on HOLE1's floor), or ``HOLE_DEPTH_M`` when it stood in none."""
    obj = cell.object(name)
    foot_local = object_foot(obj) if object_p_foot is None else object_p_foot
    world_T_obj = np.asarray(obj.world_T_object, dtype=float)
    foot = world_T_obj[:3, :3] @ foot_local + world_T_obj[:3, 3]
    for feature in cell.features.values():
        f = invert(np.asarray(feature.world_T_feature, dtype=float))
        local = f[:3, :3] @ foot + f[:3, 3]
        if local[2] < 0.0 and float(np.hypot(local[0], local[1])) <= SEAT_REACH_M:
            return float(-local[2])
    return HOLE_DEPTH_M


def seat_tcp(world_T_tcp: np.ndarray, world_T_hole: np.ndarray, depth: float, tcp_p_foot: np.ndarray) -> np.ndarray:
    """The tool pose that puts the held object's foot (``tcp_p_foot``, tool frame) on the hole's
    axis ``depth`` below its mouth, the tool's orientation kept."""
    floor = world_T_hole[:3, 3] - depth * world_T_hole[:3, 2]
    out = np.array(world_T_tcp, dtype=float)
    out[:3, 3] = floor - out[:3, :3] @ np.asarray(tcp_p_foot, dtype=float)
    return out


def arm_end(effect: TaskEffect, world_T_tcp: np.ndarray, world_T_hole: np.ndarray | None = None,
            grip: Grip | None = None, depth: float | None = None) -> np.ndarray | None:
    """Where a task with ``effect`` leaves the tool, starting at ``world_T_tcp``; None when it
    needs what it was not given (a hole to lift along or seat in, the grip of a seat)."""
    start = np.array(world_T_tcp, dtype=float)
    if effect.arm == "still":
        return start
    if effect.arm == "retreat":
        start[:3, 3] -= effect.distance_m * start[:3, 2]
        return start
    if world_T_hole is None:
        return None
    if effect.arm == "lift":
        start[:3, 3] += effect.distance_m * np.asarray(world_T_hole, dtype=float)[:3, 2]
        return start
    if grip is None:
        return None
    return seat_tcp(start, np.asarray(world_T_hole, dtype=float), HOLE_DEPTH_M if depth is None else depth, grip.tcp_p_foot)


def tool_error(world_T_a: np.ndarray, world_T_b: np.ndarray) -> tuple[float, float]:
    """How far two tool poses lie apart: the points' distance (m) and the turn between them (rad)."""
    d = float(np.linalg.norm(np.asarray(world_T_a)[:3, 3] - np.asarray(world_T_b)[:3, 3]))
    R = np.asarray(world_T_a)[:3, :3].T @ np.asarray(world_T_b)[:3, :3]
    angle = float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))
    return d, angle


def contact_end(finished: Sequence[tuple[object, bool]]) -> TaskEffect | None:
    """The declared effect of the task that last moved the arm, when contact decides its exact
    end (``TaskEffect.by_contact``) and it and every statement after it finished done; None
    otherwise. ``finished``: the statements sent, oldest first, each with whether it ended done.
    Parameter statements, tasks that keep the arm still and tasks that move it relative to where
    it is (a lift, a retreat) after it carry its offset on; an action (an absolute target) or an
    unknown task after it, or anything not done, ends the search."""
    for statement, done in reversed(list(finished)):
        if not done:
            return None
        if is_task(statement):
            spec = TASKS.get(statement.name) or TASKS.get(statement.name.lower())
            if spec is None:
                return None
            if spec.effect.by_contact:
                return spec.effect
            if spec.effect.arm in ("still", "lift", "retreat"):
                continue
            return None
        if is_action(statement):
            return None
    return None


def within_tolerance(effect: TaskEffect, world_T_robot: np.ndarray, world_T_expected: np.ndarray) -> bool:
    """The robot's tool within ``effect``'s declared tolerance of the expected tool."""
    distance, angle = tool_error(world_T_robot, world_T_expected)
    return distance <= effect.tolerance_m and angle <= max(effect.tolerance_rad, 1e-6)
