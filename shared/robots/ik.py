"""Inverse kinematics: one entry point, the solver the robot file names.

* ``puma``: closed form for the PUMA of Table 4.1, up to 8 solutions (``shared.robots.ik_puma``).
* ``rover``: closed form of seed 004 for the 3-DOF rover arm, position of point C only
  (``shared.robots.ik_rover``).
* ``dls``: damped least squares with restarts for any other robot (``shared.robots.ik_dls``).

Every solution is returned as ``(dof,)`` radians; with ``respect_limits`` each closed-form
solution is mapped into the joint ranges (adding multiples of 2 pi where a range is wider than
a turn) and dropped if it cannot be; solutions are ordered nearest to ``q_near`` first.
"""

from __future__ import annotations

import itertools

import numpy as np

from shared.errors import InputError
from shared.robots.model import LIMIT_TOLERANCE, Robot

#: two solutions closer than this (rad, max-norm) are the same solution
DUPLICATE_TOLERANCE = 1e-6


def _wrap(q: np.ndarray) -> np.ndarray:
    """Angles into (-pi, pi]."""
    return np.pi - np.mod(np.pi - q, 2.0 * np.pi)


def _in_range_variants(robot: Robot, q: np.ndarray) -> list[np.ndarray]:
    """Every ``q + 2 pi k`` (per joint) inside the joint ranges."""
    options: list[list[float]] = []
    for i, value in enumerate(_wrap(q)):
        lo, hi = robot.lower[i] - LIMIT_TOLERANCE, robot.upper[i] + LIMIT_TOLERANCE
        k_min, k_max = int(np.ceil((lo - value) / (2 * np.pi))), int(np.floor((hi - value) / (2 * np.pi)))
        vals = [value + 2 * np.pi * k for k in range(k_min, k_max + 1)]
        if not vals:
            return []
        options.append([float(np.clip(v, robot.lower[i], robot.upper[i])) for v in vals])
    return [np.array(c) for c in itertools.product(*options)]


def _dedupe(solutions: list[np.ndarray]) -> list[np.ndarray]:
    out: list[np.ndarray] = []
    for s in solutions:
        if all(np.max(np.abs(s - o)) > DUPLICATE_TOLERANCE for o in out):
            out.append(s)
    return out


def solve_ik(
    robot: Robot,
    base_T_tool: np.ndarray | None = None,
    *,
    position: np.ndarray | None = None,
    q_near: np.ndarray | None = None,
    respect_limits: bool = True,
) -> list[np.ndarray]:
    """All IK solutions for a tool pose ``base_T_tool`` (4, 4) or, for position-only robots
    (the rover), a tool ``position`` (3,). Returns an empty list when there is none."""
    if base_T_tool is None and position is None:
        raise InputError("inverse kinematics needs a target pose or position")
    q_ref = np.zeros(robot.dof) if q_near is None else robot.as_q(q_near)
    kind = robot.description.ik
    if kind == "puma":
        from shared.robots.ik_puma import puma_ik_all

        if base_T_tool is None:
            raise InputError("the PUMA needs a full tool pose (position and orientation)")
        base_T_flange = base_T_tool @ np.linalg.inv(robot.description.flange_T_tool)
        raw = puma_ik_all(robot.description.joints, base_T_flange)
    elif kind == "rover":
        from shared.robots.ik_rover import rover_ik_all

        target = np.asarray(position if position is not None else base_T_tool[:3, 3], dtype=float)  # type: ignore[index]
        raw = rover_ik_all(robot.description.joints, robot.description.flange_T_tool, target)
    else:
        from shared.robots.ik_dls import dls_ik_all

        if base_T_tool is None:
            raise InputError(f"robot {robot.name!r} needs a full tool pose for inverse kinematics")
        raw = dls_ik_all(robot, base_T_tool, q_ref)
    if respect_limits:
        candidates = [v for q in raw for v in _in_range_variants(robot, q)]
    else:
        candidates = [_wrap(q) for q in raw]
    candidates = _dedupe(candidates)
    candidates.sort(key=lambda q: float(np.sum((q - q_ref) ** 2)))
    return candidates
