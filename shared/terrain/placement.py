"""Instrument placement (seed 004's in-situ detection): for a target point on the terrain, the
arm configurations that put point C (the X-ray spectrometer's centre) within ``max_standoff``
of the surface along its normal, with no other part of the arm nearer the ground than a safety
margin and the instrument head itself not touching; ranked by clearance, with the statement
program that gets there (an approach pose along the normal, then the final pose, slower).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shared.errors import InputError, UnreachableError
from shared.language.statements import Event, Move, SetSpeed, Speed, SpeedUnit
from shared.robots.ik import solve_ik
from shared.spatial import invert
from shared.terrain.checks import TerrainChecker

#: C within this of the surface along the normal (seed 004: 30 mm)
MAX_STANDOFF = 0.030
#: standoffs tried, as fractions of the maximum (nearest first is the instrument's preference)
STANDOFF_FRACTIONS = (0.5, 0.33, 0.67, 0.85, 1.0)
#: default clearance of every part but the instrument head (m)
SAFETY_MARGIN = 0.020
#: the head may come this close (m) and no closer
HEAD_MARGIN = 0.002
#: radius (m) over which the surface normal is averaged (about the instrument's footprint)
NORMAL_RADIUS = 0.030
#: approach distances tried above the final point along the normal (m)
APPROACH = (0.100, 0.060, 0.040)
PATH_SAMPLES = 12


@dataclass(frozen=True)
class PlacementCandidate:
    q: np.ndarray  # final joint vector (rad)
    standoff: float  # C's height above the target along the normal (m)
    clearance: float  # smallest distance of the arm without its head (m)
    head_clearance: float  # the instrument head's distance (m)
    tilt: float  # angle between the head's axis and the normal (rad)
    q_approach: np.ndarray | None
    path_clearance: float  # smallest clearance along approach -> final (m), inf without approach


@dataclass(frozen=True)
class PlacementResult:
    world_p_target: np.ndarray
    world_n_surface: np.ndarray
    candidates: tuple[PlacementCandidate, ...]
    rejected: dict[str, int] = field(default_factory=dict)
    program: tuple = ()

    @property
    def best(self) -> PlacementCandidate | None:
        return self.candidates[0] if self.candidates else None


def surface_normal(checker: TerrainChecker, world_p: np.ndarray, radius: float = NORMAL_RADIUS) -> np.ndarray:
    """Area-weighted mean normal (pointing up) of the terrain triangles within ``radius``."""
    ids = checker.triangles_near_shapes(np.eye(3)[None], np.asarray(world_p, float)[None], np.array([0]),
                                        np.array([[radius, 0.0, 0.0, 0.0, 0.0]]), 0.0)
    tree = checker.tree
    if len(ids) == 0:
        raise InputError(f"target ({', '.join(f'{v * 1e3:.1f}' for v in world_p)}) mm is not on the terrain "
                         f"(no triangle within {radius * 1e3:.0f} mm)")
    pos = np.flatnonzero(np.isin(tree.face_ids, ids))
    v = tree.vertices[tree.faces[pos]]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]).sum(axis=0)  # cross is twice the area
    n /= np.linalg.norm(n)
    return n if n[2] >= 0 else -n


def terrain_point_at(checker: TerrainChecker, x: float, y: float) -> np.ndarray:
    """The terrain point straight below/above ground position (x, y) (world, m): what a click on
    the map or a typed ground position means."""
    from shared.terrain.tree import ray_hits

    tree = checker.tree
    top = float(tree.hi[0, 2]) + 1.0
    t = np.empty(1)
    pos = np.empty(1, np.int64)
    ray_hits(np.array([[x, y, top]]), np.array([[0.0, 0.0, -1.0]]), top - float(tree.lo[0, 2]) + 1.0, *tree.arrays(), t, pos)
    if pos[0] < 0:
        raise InputError(f"ground position ({x * 1e3:.1f}, {y * 1e3:.1f}) mm is outside the terrain")
    return np.array([x, y, top - t[0]])


def _head_axis(checker: TerrainChecker, q: np.ndarray) -> np.ndarray:
    arm = checker.arm
    Rs, _ = arm.shape_poses(checker.world_T_base, q)
    part = next(p for p in arm.parts if arm.tool_shape in p.shape_indices)
    A, B, _ = arm.sensors(checker.world_T_base, q, (arm.parts.index(part),))
    axis = (B - A).mean(axis=0)
    return axis / np.linalg.norm(axis)


def plan_placement(
    checker: TerrainChecker,
    world_p_target: np.ndarray,
    *,
    max_standoff: float = MAX_STANDOFF,
    margin: float = SAFETY_MARGIN,
    head_margin: float = HEAD_MARGIN,
    speed: float = 0.3,
    approach_speed: float = 0.1,
) -> PlacementResult:
    """All placements within the joint ranges for a target on the terrain, best first."""
    target = np.asarray(world_p_target, dtype=float).reshape(3)
    if not np.all(np.isfinite(target)):
        raise InputError("placement target has NaN or infinite coordinates")
    if not 0 < max_standoff <= 0.2:
        raise InputError(f"max standoff must be in (0, 200] mm, got {max_standoff * 1e3:.1f} mm")
    robot = checker.arm.robot
    base_T_world = invert(checker.world_T_base)
    normal = surface_normal(checker, target)
    n_shapes = len(checker.arm.shapes)
    groups = np.zeros(n_shapes, np.int64)
    groups[checker.arm.tool_shape] = 1  # group 0: the arm without its head, group 1: the head

    def clearances(q: np.ndarray) -> tuple[float, float]:
        d, *_ = checker.group_distances(q, groups, 2)
        return float(d[0]), float(d[1])

    rejected = {"unreachable": 0, "arm_too_close": 0, "head_touches": 0}
    found: list[PlacementCandidate] = []
    for frac in STANDOFF_FRACTIONS:
        standoff = frac * max_standoff
        world_p_c = target + standoff * normal
        base_p_c = (base_T_world @ np.append(world_p_c, 1.0))[:3]
        sols = solve_ik(robot, position=base_p_c, respect_limits=True)
        if not sols:
            rejected["unreachable"] += 1
            continue
        for q in sols:
            arm_d, head_d = clearances(q)
            if arm_d < margin:
                rejected["arm_too_close"] += 1
                continue
            if head_d < head_margin:
                rejected["head_touches"] += 1
                continue
            q_app, path_d = None, np.inf
            for extra in APPROACH:
                p_app = (base_T_world @ np.append(world_p_c + extra * normal, 1.0))[:3]
                apps = solve_ik(robot, position=p_app, q_near=q, respect_limits=True)
                if not apps:
                    continue
                qa = apps[0]
                worst, head_ok = np.inf, True
                for s in np.linspace(0.0, 1.0, PATH_SAMPLES):
                    a, h = clearances(qa + s * (q - qa))
                    worst = min(worst, a)
                    head_ok = head_ok and h >= head_margin
                if worst >= margin and head_ok:
                    q_app, path_d = qa, worst
                    break
            tilt = float(np.arccos(np.clip(abs(np.dot(_head_axis(checker, q), normal)), -1.0, 1.0)))
            found.append(PlacementCandidate(q, standoff, arm_d, head_d, tilt, q_app, path_d))
    # one entry per distinct configuration branch: keep the best standoff of near-equal joints
    found.sort(key=lambda c: (-(c.q_approach is not None), -c.clearance, c.tilt))
    unique: list[PlacementCandidate] = []
    for c in found:
        if all(np.max(np.abs(c.q - u.q)) > np.radians(5.0) for u in unique):
            unique.append(c)
    program: tuple = ()
    if unique:
        best = unique[0]
        steps: list = [SetSpeed(speed=Speed(value=speed, unit=SpeedUnit.FRACTION))]
        if best.q_approach is not None:
            steps.append(Move(joints=_rounded(best.q_approach)))
            steps.append(SetSpeed(speed=Speed(value=approach_speed, unit=SpeedUnit.FRACTION)))
        steps.append(Move(joints=_rounded(best.q)))
        steps.append(Event(name="instrument_placed"))
        program = tuple(steps)
    return PlacementResult(target, normal, tuple(unique), rejected, program)


def _rounded(q: np.ndarray) -> tuple[float, ...]:
    """Joint targets rounded to 0.001 deg so the statement text stays readable."""
    return tuple(float(np.radians(round(float(np.degrees(v)), 3))) for v in q)


def require_placement(result: PlacementResult) -> PlacementCandidate:
    """The best placement or an ``UnreachableError`` saying why there is none."""
    if result.best is None:
        why = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in result.rejected.items() if v)
        raise UnreachableError(f"no safe instrument placement at that target ({why or 'no IK solution'})")
    return result.best
