"""The rover arm as the terrain checks see it: its link shapes as convex primitives (for the
exact distance) and the paper's virtual sensors (for the seed 004 check).

Virtual sensors (seed 004 §3.1 step 1): each arm part is wrapped by ``n`` segments parallel to
its axis on a circle of the part's largest radius, like laser range finders fixed to the link.
A part here is a set of coaxial shapes of one link (the forearm and the spectrometer head form
one part, the paper's E). Each sensor runs from A to B toward the distal end of the part.

Numbering (the paper's Tables 3-5 number the E part's sensors 1..36; its text and Figure 5 do not
say where 1 sits or which way the count runs, so this is a choice): sensor 1 lies on the part's
circle in the direction ``u = axis x e`` (``e`` the link frame's x axis, its y axis when the part
runs along x), and the count runs right-handed about the axis A -> B, 360/n degrees a step. On the
rover's forearm-and-head part (axis +y of link 3) sensor 1 is on link 3's -z side. At the paper's
clear pose over flat ground this puts the lowest sensor at number 10, where Table 3 has its
minimum; the mirrored count fits Table 3 as well (the pattern is symmetric about sensor 10).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.errors import InputError
from shared.robots.model import Robot
from shared.terrain.gjk import KIND_CODES

#: two shape axes closer than this (m) and parallel count as one part
COAXIAL_TOL = 1e-3


@dataclass(frozen=True)
class ArmShape:
    """One convex shape of a link: ``link_T_shape`` (4, 4), ``kind`` code, ``par`` as in gjk."""

    name: str
    link: int
    kind: int
    par: np.ndarray
    link_T_shape: np.ndarray


@dataclass(frozen=True)
class SensorPart:
    """A part wrapped by sensors: ``link_A`` / ``link_B`` (n, 3) sensor ends in the link frame."""

    name: str
    link: int
    shape_indices: tuple[int, ...]
    radius: float
    link_A: np.ndarray
    link_B: np.ndarray


@dataclass(frozen=True)
class ArmModel:
    """The arm's shapes, their kinds and parameters stacked for the numba queries, the index of
    the shape carrying the tool point (the instrument head) and the sensor parts."""

    robot: Robot
    shapes: tuple[ArmShape, ...]
    kinds: np.ndarray
    pars: np.ndarray
    tool_shape: int
    parts: tuple[SensorPart, ...]

    def shape_poses(self, world_T_base: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (S, 3, 3) and origins (S, 3) of every shape in the world at ``q``."""
        base_T_links = self.robot.link_poses(q)
        world_T_shapes = np.stack([world_T_base @ base_T_links[s.link] @ s.link_T_shape for s in self.shapes])
        return np.ascontiguousarray(world_T_shapes[:, :3, :3]), np.ascontiguousarray(world_T_shapes[:, :3, 3])

    def sensors(self, world_T_base: np.ndarray, q: np.ndarray, parts: tuple[int, ...] | None = None):
        """World sensor ends A, B (M, 3) and the part index of each sensor."""
        base_T_links = self.robot.link_poses(q)
        chosen = range(len(self.parts)) if parts is None else parts
        As, Bs, owner = [], [], []
        for p in chosen:
            part = self.parts[p]
            world_T_link = world_T_base @ base_T_links[part.link]
            As.append(part.link_A @ world_T_link[:3, :3].T + world_T_link[:3, 3])
            Bs.append(part.link_B @ world_T_link[:3, :3].T + world_T_link[:3, 3])
            owner.append(np.full(len(part.link_A), p))
        return np.concatenate(As), np.concatenate(Bs), np.concatenate(owner)


def head_part(arm: ArmModel) -> int:
    """Index of the part that carries the instrument head (seed 004's E\\5: forearm and head)."""
    return next(i for i, p in enumerate(arm.parts) if arm.tool_shape in p.shape_indices)


def _axis_extent(shape: ArmShape) -> tuple[np.ndarray, float, float, float]:
    """Axis direction (link frame), its extent (z0, z1) along it and the radius of the smallest
    circle around the axis that holds the shape's cross-section."""
    R = shape.link_T_shape[:3, :3]
    r, h, hx, hy, hz = shape.par
    if shape.kind == KIND_CODES["box"]:
        halves = np.array([hx, hy, hz])
        a = int(np.argmax(halves))
        others = [i for i in range(3) if i != a]
        return R[:, a], -halves[a], halves[a], float(np.hypot(*halves[others]))
    if shape.kind == KIND_CODES["capsule"]:
        return R[:, 2], -(h + r), h + r, r
    if shape.kind == KIND_CODES["sphere"]:
        return R[:, 2], -r, r, r
    return R[:, 2], -h, h, r


def _parts(shapes: tuple[ArmShape, ...], n_sensors: int) -> tuple[SensorPart, ...]:
    groups: list[list[int]] = []
    for i, s in enumerate(shapes):
        axis, _, _, _ = _axis_extent(s)
        origin = s.link_T_shape[:3, 3]
        for g in groups:
            first = shapes[g[0]]
            if first.link != s.link:
                continue
            axis_g, _, _, _ = _axis_extent(first)
            offset = origin - first.link_T_shape[:3, 3]
            off_axis = offset - np.dot(offset, axis_g) * axis_g
            if abs(abs(np.dot(axis, axis_g)) - 1.0) < 1e-9 and np.linalg.norm(off_axis) < COAXIAL_TOL:
                g.append(i)
                break
        else:
            groups.append([i])
    parts = []
    angles = 2.0 * np.pi * np.arange(n_sensors) / n_sensors
    for g in groups:
        first = shapes[g[0]]
        axis, _, _, _ = _axis_extent(first)
        point = first.link_T_shape[:3, 3]
        z0s, z1s, radius = [], [], 0.0
        for i in g:
            ax, a, b, r = _axis_extent(shapes[i])
            centre = float(np.dot(shapes[i].link_T_shape[:3, 3] - point, axis))
            z0s.append(centre - b)
            z1s.append(centre + b)
            radius = max(radius, r)
        z0, z1 = min(z0s), max(z1s)
        mid = point + axis * 0.5 * (z0 + z1)
        if np.dot(mid, axis) < -1e-12:  # sensors point away from the link's joint (distal)
            axis, z0, z1 = -axis, -z1, -z0
        u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        w = np.cross(axis, u)
        ring = radius * (np.outer(np.cos(angles), u) + np.outer(np.sin(angles), w))
        name = " + ".join(shapes[i].name for i in g)
        parts.append(SensorPart(name, first.link, tuple(g), radius, point + axis * z0 + ring, point + axis * z1 + ring))
    return tuple(parts)


def arm_model(robot: Robot, n_sensors: int = 36) -> ArmModel:
    """The arm model of a robot from its link geometry (boxes, spheres, cylinders, capsules)."""
    if n_sensors < 1:
        raise InputError(f"each part needs at least one virtual sensor, got {n_sensors}")
    shapes = []
    for link in sorted(robot.shapes):
        for k, shape in enumerate(robot.shapes[link]):
            if shape.kind not in KIND_CODES:
                raise InputError(f"robot {robot.name!r}: link {link} shape {k} is a {shape.kind}; terrain checks need "
                                 "boxes, spheres, cylinders or capsules")
            half = np.asarray(shape.size, dtype=float) / 2.0
            par = np.array([shape.radius, shape.length / 2.0, half[0], half[1], half[2]])
            shapes.append(ArmShape(f"link{link}.{shape.kind}{k}", link, KIND_CODES[shape.kind], par,
                                   np.asarray(shape.link_T_shape, dtype=float)))
    if not shapes:
        raise InputError(f"robot {robot.name!r} has no link geometry to check against the terrain")
    shapes_t = tuple(shapes)
    # the instrument head: the shape of the last link nearest to the tool point
    last = max(s.link for s in shapes_t)
    q0 = np.clip(np.zeros(robot.dof), robot.lower, robot.upper)
    tool_p = (np.linalg.inv(robot.link_poses(q0)[last]) @ robot.fk(q0))[:3, 3]  # C in the last link's frame
    cands = [i for i, s in enumerate(shapes_t) if s.link == last]
    tool_shape = min(cands, key=lambda i: np.linalg.norm(shapes_t[i].link_T_shape[:3, 3] - tool_p))
    kinds = np.array([s.kind for s in shapes_t], dtype=np.int64)
    pars = np.ascontiguousarray(np.stack([s.par for s in shapes_t]))
    return ArmModel(robot, shapes_t, kinds, pars, tool_shape, _parts(shapes_t, n_sensors))
