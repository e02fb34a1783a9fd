"""Inverse kinematics: one entry point, the solver the robot file names.

* ``puma``: closed form for the PUMA of Table 4.1, up to 8 solutions (``shared.robots.ik_puma``).
* ``rover``: closed form of seed 004 for the 3-DOF rover arm, position of point C only
  (``shared.robots.ik_rover``).
* ``dls``: damped least squares with restarts for any other robot (``shared.robots.ik_dls``).

Every solution is returned as ``(dof,)`` radians; with ``respect_limits`` each closed-form
solution is mapped into the joint ranges (adding multiples of 2 pi where a range is wider than
a turn) and dropped if it cannot be, except that one within the robot's ``ik_limit_tolerance``
of a range is clamped onto its limit; solutions are ordered nearest to ``q_near`` first.

Callers that want only the nearest solution (jogging, the planner's next step, the program
checks) use ``shared.robots.ik_kernels.solve_ik_nearest``: the same first solution, computed in
one compiled call for the PUMA; keep the two in step when changing the rules here.
"""

from __future__ import annotations

import itertools

import numpy as np

from shared.errors import InputError
from shared.robots.model import LIMIT_TOLERANCE, Robot
from shared.spatial import invert

#: two solutions closer than this (rad, max-norm) are the same solution
DUPLICATE_TOLERANCE = 1e-6


def _wrap(q: np.ndarray) -> np.ndarray:
    """Angles into (-pi, pi] (``np.mod`` may round up to 2 pi: fold that back)."""
    out = np.pi - np.mod(np.pi - q, 2.0 * np.pi)
    return np.where(out <= -np.pi, out + 2.0 * np.pi, out)


def _in_range_variants(robot: Robot, raw: np.ndarray, tolerance: float = LIMIT_TOLERANCE) -> list[np.ndarray]:
    """Every ``q + 2 pi k`` (per joint) inside the joint ranges widened by ``tolerance`` (rad),
    for each row of ``raw`` (n, dof); a value in the widened band is clamped to its limit."""
    wrapped = _wrap(raw)
    two_pi = 2.0 * np.pi
    k_min = np.ceil((robot.lower - tolerance - wrapped) / two_pi).astype(int)
    k_max = np.floor((robot.upper + tolerance - wrapped) / two_pi).astype(int)
    feasible = np.all(k_max >= k_min, axis=1)
    single = feasible & np.all(k_max == k_min, axis=1)
    base = np.clip(wrapped + two_pi * k_min, robot.lower, robot.upper)
    out: list[np.ndarray] = []
    for row in np.flatnonzero(feasible):
        if single[row]:  # the common case: one representative per joint
            out.append(base[row])
            continue
        options = [
            np.clip(wrapped[row, i] + two_pi * np.arange(k_min[row, i], k_max[row, i] + 1), robot.lower[i], robot.upper[i])
            for i in range(robot.dof)
        ]
        out.extend(np.array(c) for c in itertools.product(*options))
    return out


def _dedupe(solutions: list[np.ndarray]) -> list[np.ndarray]:
    """Drop solutions within ``DUPLICATE_TOLERANCE`` of an earlier one (max-norm)."""
    if len(solutions) < 2:
        return solutions
    arr = np.stack(solutions)
    close = np.max(np.abs(arr[:, None, :] - arr[None, :, :]), axis=2) <= DUPLICATE_TOLERANCE
    keep = ~np.any(np.tril(close, k=-1), axis=1)
    return [s for s, k in zip(solutions, keep) if k]


def distinct_branches(solutions: list[np.ndarray]) -> list[tuple[np.ndarray, int]]:
    """Group solutions that differ only by whole turns of some joints (the same arm posture
    reached with a joint wound 2 pi further): per group, its first solution (the list is sorted
    nearest-first, so the nearest) and how many turn variants the group holds. A UR5 with
    +-2 pi ranges has up to 64 variants of each of its 8 postures."""
    groups: dict[tuple, int] = {}
    firsts: list[np.ndarray] = []
    counts: list[int] = []
    for q in solutions:
        key = tuple(np.round(_wrap(q) / DUPLICATE_TOLERANCE).astype(np.int64).tolist())
        k = groups.get(key)
        if k is None:
            groups[key] = len(firsts)
            firsts.append(q)
            counts.append(1)
        else:
            counts[k] += 1
    return list(zip(firsts, counts))


def positions_tool_only(robot: Robot) -> bool:
    """Does ``robot``'s inverse kinematics place the tool point only, with no orientation (the
    rover's arm)? Every caller that chooses between a pose and a position asks this."""
    return robot.description.ik == "rover"


def ik_target(robot: Robot, base_T_tool: np.ndarray) -> dict[str, np.ndarray]:
    """The keyword arguments of ``solve_ik`` / ``solve_ik_nearest`` for the tool pose
    ``base_T_tool``: the whole pose, or its position for robots that place the tool point only."""
    return {"position": base_T_tool[:3, 3]} if positions_tool_only(robot) else {"base_T_tool": base_T_tool}


def solve_ik(
    robot: Robot,
    base_T_tool: np.ndarray | None = None,
    *,
    position: np.ndarray | None = None,
    q_near: np.ndarray | None = None,
    respect_limits: bool = True,
    limit_tolerance: float | None = None,
) -> list[np.ndarray]:
    """All IK solutions for a tool pose ``base_T_tool`` (4, 4) or, for position-only robots
    (the rover), a tool ``position`` (3,). Returns an empty list when there is none.

    With ``respect_limits``, a solution up to ``limit_tolerance`` (rad; default the robot
    file's ``ik_limit_tolerance``, none unless the file sets one) past a joint limit is returned
    at that limit."""
    if base_T_tool is None and position is None:
        raise InputError("inverse kinematics needs a target pose or position")
    q_ref = np.zeros(robot.dof) if q_near is None else robot.as_q(q_near)
    kind = robot.description.ik
    if kind == "puma":
        from shared.robots.ik_puma import puma_ik_all

        if base_T_tool is None:
            raise InputError("the PUMA needs a full tool pose (position and orientation)")
        base_T_flange = invert(robot.description.base_T_chain) @ base_T_tool @ invert(robot.description.flange_T_tool)
        raw = puma_ik_all(robot.description.joints, base_T_flange, q4_singular=float(q_ref[3]))
    elif kind == "rover":
        from shared.robots.ik_rover import rover_ik_all

        target = np.asarray(position if position is not None else base_T_tool[:3, 3], dtype=float)  # type: ignore[index]
        chain_p_target = invert(robot.description.base_T_chain) @ np.append(target, 1.0)
        raw = rover_ik_all(robot.description.joints, robot.description.flange_T_tool, chain_p_target[:3])
    else:
        from shared.robots.ik_dls import dls_ik_all

        if base_T_tool is None:
            raise InputError(f"robot {robot.name!r} needs a full tool pose for inverse kinematics")
        raw = dls_ik_all(robot, base_T_tool, q_ref)
    if not raw:
        return []
    raw_arr = np.stack(raw)
    if limit_tolerance is None:
        limit_tolerance = robot.description.ik_limit_tolerance
    if not limit_tolerance >= 0.0:
        raise InputError(f"the IK limit tolerance must be zero or more; got {limit_tolerance}")
    candidates = (
        _in_range_variants(robot, raw_arr, max(limit_tolerance, LIMIT_TOLERANCE)) if respect_limits else list(_wrap(raw_arr))
    )
    candidates = _dedupe(candidates)
    if len(candidates) > 1:
        order = np.argsort(np.sum((np.stack(candidates) - q_ref) ** 2, axis=1), kind="stable")
        candidates = [candidates[i] for i in order]
    return candidates
