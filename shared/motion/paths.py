"""Geometric paths ``q(s)``, ``s`` in [0, 1]: what a motion statement traces, before timing.

* ``JointPath``: straight line in joint space (MOVE, DRIVE). All joints move in proportion, so
  one scalar time law synchronises them.
* ``NodePath``: a straight tool line with slerped orientation (DRAW, ROTATE, MOVES), resolved
  to joints by inverse kinematics at nodes along the line, each solution the one nearest the
  previous node, and joined by cubic Hermite interpolation. Nodes are added where the
  interpolated tool strays from the ideal line by more than ``POSITION_TOLERANCE`` /
  ``ANGLE_TOLERANCE`` or where the joints change too much between nodes; a change that does not
  shrink when nodes are added is a jump to another arm configuration, and the path is refused.

Both expose ``q``, ``dq`` (dq/ds) and ``ddq`` (d2q/ds2) vectorised over ``s``, and ``bounds``:
the largest ``|dq/ds|`` and ``|d2q/ds2|`` per joint, which the time law uses to keep every joint
within its velocity and acceleration limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from shared.motion.frames import CellFrames
from shared.motion.refusal import PlanRefused, RefusalReason
from shared.robots.ik import ik_target, positions_tool_only, solve_ik
from shared.robots.ik_kernels import solve_ik_nearest
from shared.robots.model import Robot
from shared.spatial import exp_so3, log_so3

#: largest distance (m) of the interpolated tool point from the ideal line at any node midpoint
POSITION_TOLERANCE = 2e-5
#: largest angle (rad) between the interpolated and the slerped tool orientation at a midpoint
ANGLE_TOLERANCE = 2e-4
#: initial node spacing along the line (m) and in rotation (rad)
NODE_STEP_LENGTH = 0.025
NODE_STEP_ANGLE = math.radians(10.0)
#: largest change of any joint (rad) between neighbouring nodes before nodes are added
JOINT_STEP_LIMIT = math.radians(10.0)
#: smallest node spacing (m of line, rad of rotation); a joint step still too large is a jump
MIN_NODE_LENGTH = 2e-5
MIN_NODE_ANGLE = 2e-5
#: rounds of refinement before giving up on a path
MAX_REFINEMENTS = 40
#: safety margin on the derivative bounds sampled from the interpolant
BOUND_MARGIN = 1.02


@dataclass(frozen=True)
class JointPath:
    """``q(s) = q_start + s (q_end - q_start)``."""

    q_start: np.ndarray
    q_end: np.ndarray

    @property
    def delta(self) -> np.ndarray:
        return self.q_end - self.q_start

    def q(self, s: np.ndarray) -> np.ndarray:
        return self.q_start + np.asarray(s, dtype=float)[..., None] * self.delta

    def dq(self, s: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.delta, np.shape(s) + self.delta.shape).copy()

    def ddq(self, s: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(s) + self.delta.shape)

    def q_dq_ddq(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.q(s), self.dq(s), self.ddq(s)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.abs(self.delta), np.zeros_like(self.delta)


def _tangents(s: np.ndarray, q: np.ndarray) -> np.ndarray:
    """dq/ds at every node: second-order finite differences on the (non-uniform) node grid."""
    n = s.size
    if n == 2:
        slope = (q[1] - q[0]) / (s[1] - s[0])
        return np.stack([slope, slope])
    h = np.diff(s)
    out = np.empty_like(q)
    h0 = h[:-1, None]
    h1 = h[1:, None]
    out[1:-1] = (h0 * h0 * (q[2:] - q[1:-1]) + h1 * h1 * (q[1:-1] - q[:-2])) / (h0 * h1 * (h0 + h1))
    a, b = h[0], h[1]
    out[0] = -(2 * a + b) / (a * (a + b)) * q[0] + (a + b) / (a * b) * q[1] - a / (b * (a + b)) * q[2]
    a, b = h[-2], h[-1]
    out[-1] = b / (a * (a + b)) * q[-3] - (a + b) / (a * b) * q[-2] + (2 * b + a) / (b * (a + b)) * q[-1]
    return out


def hermite(
    p0: np.ndarray, p1: np.ndarray, m0: np.ndarray, m1: np.ndarray, h: np.ndarray, u: np.ndarray, order: int
) -> np.ndarray:
    """Cubic Hermite interpolation on intervals of length ``h`` between values ``p0``, ``p1``
    (n, dof) with slopes ``m0``, ``m1``, at fractions ``u`` (n,): the value (``order`` 0) or its
    first or second derivative with respect to the interval's parameter."""
    if u.size == 1:  # one servo step's sample: the coefficients as floats, 4 vector operations
        return _hermite_one(p0, p1, m0, m1, float(h.reshape(-1)[0]), float(u.reshape(-1)[0]), order)
    if order == 0:
        u2, u3 = u * u, u * u * u
        c00, c10, c01, c11, scale = 2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2, None
    elif order == 1:
        u2 = u * u
        c00, c10, c01, c11, scale = 6 * u2 - 6 * u, 3 * u2 - 4 * u + 1, -6 * u2 + 6 * u, 3 * u2 - 2 * u, h
    else:
        c00, c10, c01, c11, scale = 12 * u - 6, 6 * u - 4, -12 * u + 6, 6 * u - 2, h * h
    hh = h[..., None]
    out = c00[..., None] * p0 + c10[..., None] * hh * m0 + c01[..., None] * p1 + c11[..., None] * hh * m1
    return out if scale is None else out / scale[..., None]


def _hermite_one(p0: np.ndarray, p1: np.ndarray, m0: np.ndarray, m1: np.ndarray, h: float, u: float,
                 order: int) -> np.ndarray:
    """``hermite`` at a single fraction ``u`` (the same formulas, scalar coefficients)."""
    if order == 0:
        u2, u3 = u * u, u * u * u
        c00, c10, c01, c11, scale = 2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2, 1.0
    elif order == 1:
        u2 = u * u
        c00, c10, c01, c11, scale = 6 * u2 - 6 * u, 3 * u2 - 4 * u + 1, -6 * u2 + 6 * u, 3 * u2 - 2 * u, h
    else:
        c00, c10, c01, c11, scale = 12 * u - 6, 6 * u - 4, -12 * u + 6, 6 * u - 2, h * h
    out = c00 * p0 + (c10 * h) * m0 + c01 * p1 + (c11 * h) * m1
    return out if order == 0 else out / scale


@dataclass(frozen=True)
class NodePath:
    """Cubic Hermite interpolation of joint vectors ``q_nodes`` (m, dof) at ``s_nodes`` (m,)."""

    s_nodes: np.ndarray
    q_nodes: np.ndarray
    tangents: np.ndarray

    @classmethod
    def through(cls, s_nodes: np.ndarray, q_nodes: np.ndarray) -> "NodePath":
        return cls(s_nodes, q_nodes, _tangents(s_nodes, q_nodes))

    @property
    def q_start(self) -> np.ndarray:
        return self.q_nodes[0]

    @property
    def q_end(self) -> np.ndarray:
        return self.q_nodes[-1]

    def _locate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s = np.clip(np.asarray(s, dtype=float), 0.0, 1.0)
        k = np.clip(np.searchsorted(self.s_nodes, s, side="right") - 1, 0, self.s_nodes.size - 2)
        h = self.s_nodes[k + 1] - self.s_nodes[k]
        u = (s - self.s_nodes[k]) / h
        return k, h, u

    def _eval(self, s: np.ndarray, order: int) -> np.ndarray:
        k, h, u = self._locate(s)
        return hermite(self.q_nodes[k], self.q_nodes[k + 1], self.tangents[k], self.tangents[k + 1], h, u, order)

    def q(self, s: np.ndarray) -> np.ndarray:
        return self._eval(s, 0)

    def q_dq_ddq(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``q``, ``dq/ds`` and ``d2q/ds2`` at ``s``, the interval located once (a servo step's
        sample needs all three)."""
        k, h, u = self._locate(s)
        p0, p1, m0, m1 = self.q_nodes[k], self.q_nodes[k + 1], self.tangents[k], self.tangents[k + 1]
        return tuple(hermite(p0, p1, m0, m1, h, u, order) for order in (0, 1, 2))  # type: ignore[return-value]

    def dq(self, s: np.ndarray) -> np.ndarray:
        return self._eval(s, 1)

    def ddq(self, s: np.ndarray) -> np.ndarray:
        return self._eval(s, 2)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Largest ``|dq/ds|`` and ``|d2q/ds2|`` per joint, sampled 5 times per interval (the second
        derivative is linear on an interval, so its ends bound it; the first is quadratic)."""
        lo, hi = self.s_nodes[:-1], self.s_nodes[1:]
        fractions = np.array([0.0, 0.25, 0.5, 0.75, 1.0 - 1e-12])
        s = (lo[:, None] + (hi - lo)[:, None] * fractions[None, :]).ravel()
        return (
            np.max(np.abs(self.dq(s)), axis=0) * BOUND_MARGIN,
            np.max(np.abs(self.ddq(s)), axis=0) * BOUND_MARGIN,
        )


@dataclass(frozen=True)
class ToolLine:
    """The ideal Cartesian path: tool point on a straight line, orientation slerped (world frame)."""

    world_T_start: np.ndarray
    world_T_goal: np.ndarray

    @property
    def offset(self) -> np.ndarray:
        return self.world_T_goal[:3, 3] - self.world_T_start[:3, 3]

    @property
    def rotvec(self) -> np.ndarray:
        """Rotation from start to goal as a vector in the start's tool axes."""
        return log_so3(self.world_T_start[:3, :3].T @ self.world_T_goal[:3, :3])

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.offset))

    @property
    def angle(self) -> float:
        return float(np.linalg.norm(self.rotvec))

    def positions(self, s: np.ndarray) -> np.ndarray:
        return self.world_T_start[:3, 3] + np.asarray(s, dtype=float)[..., None] * self.offset

    def pose(self, s: float) -> np.ndarray:
        out = np.eye(4)
        out[:3, :3] = self.world_T_start[:3, :3] @ exp_so3(s * self.rotvec)
        out[:3, 3] = self.world_T_start[:3, 3] + s * self.offset
        return out


def solve_nearest(robot: Robot, frames: CellFrames, world_T_tcp: np.ndarray, q_near: np.ndarray, at: float) -> np.ndarray:
    """The IK solution nearest ``q_near`` within the joint ranges, or a refusal saying why not."""
    base_T_tool = frames.base_T_tool(world_T_tcp)
    target = ik_target(robot, base_T_tool)
    best = solve_ik_nearest(robot, q_seed=q_near, **target)
    if best is not None:
        return best
    where = 1e3 * world_T_tcp[:3, 3]
    place = f"({where[0]:.1f}, {where[1]:.1f}, {where[2]:.1f}) mm in WORLD ({100 * at:.1f} % of the line)"
    free = solve_ik(robot, q_near=q_near, respect_limits=False, **target)
    if free:
        joint, bound = _first_outside(robot, _nearest_unwrapped(free, q_near))
        raise PlanRefused(
            RefusalReason.JOINT_LIMIT,
            f"tool pose at {place} needs joint {joint + 1} beyond its limit of {math.degrees(bound):.1f} deg",
            at=at,
        )
    raise PlanRefused(RefusalReason.UNREACHABLE, f"tool pose at {place} is out of the robot's reach", at=at)


def _nearest_unwrapped(solutions: list[np.ndarray], q_prev: np.ndarray) -> np.ndarray:
    """The solver wraps angles into one turn: unwrap each solution next to ``q_prev`` and return
    the nearest (max-norm)."""
    near = q_prev + (np.mod(np.stack(solutions) - q_prev + np.pi, 2.0 * np.pi) - np.pi)
    return near[int(np.argmin(np.max(np.abs(near - q_prev), axis=1)))]


def _first_outside(robot: Robot, q: np.ndarray) -> tuple[int, float]:
    """The first joint of ``q`` outside its range and the limit it passes."""
    outside = (q < robot.lower) | (q > robot.upper)
    joint = int(np.flatnonzero(outside)[0]) if np.any(outside) else 0
    return joint, float(robot.upper[joint] if q[joint] > robot.upper[joint] else robot.lower[joint])


def _tool_errors(robot: Robot, frames: CellFrames, line: ToolLine, s: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m) and angle (rad) of the tool at joint vectors ``q`` (k, dof) from the ideal
    line at ``s`` (k,)."""
    k = s.size
    pos_err = np.empty(k)
    ang_err = np.empty(k)
    ideal_p = line.positions(s)
    check_angle = not positions_tool_only(robot)
    for i in range(k):
        actual = frames.world_T_tcp(robot, q[i])
        pos_err[i] = np.linalg.norm(actual[:3, 3] - ideal_p[i])
        if check_angle:
            ideal_r = line.pose(float(s[i]))[:3, :3]
            c = (np.trace(ideal_r.T @ actual[:3, :3]) - 1.0) / 2.0
            ang_err[i] = math.acos(max(-1.0, min(1.0, c)))
        else:
            ang_err[i] = 0.0
    return pos_err, ang_err


def _explain_limit(robot: Robot, frames: CellFrames, line: ToolLine, s: float, q_prev: np.ndarray) -> None:
    """Before refusing a path as a jump: if the arm's own branch goes on just outside a joint's
    range, the honest reason is that joint's limit; raise that instead."""
    base_T_tool = frames.base_T_tool(line.pose(s))
    free = solve_ik(robot, q_near=q_prev, respect_limits=False, **ik_target(robot, base_T_tool))
    if not free:
        return
    q = _nearest_unwrapped(free, q_prev)
    if np.max(np.abs(q - q_prev)) > JOINT_STEP_LIMIT or robot.within_limits(q):
        return
    joint, bound = _first_outside(robot, q)
    raise PlanRefused(
        RefusalReason.JOINT_LIMIT,
        f"the line takes joint {joint + 1} past its limit of {math.degrees(bound):.1f} deg at {100 * s:.1f} % of the line",
        at=s,
    )


def build_tool_path(robot: Robot, frames: CellFrames, q_start: np.ndarray, line: ToolLine) -> NodePath:
    """Resolve ``line`` to joints, starting from ``q_start`` (whose tool pose is the line's start).

    Raises ``PlanRefused`` (unreachable, joint_limit, joint_jump) with ``at`` = where on the line.
    """
    length, angle = line.length, line.angle
    count = max(1, math.ceil(length / NODE_STEP_LENGTH), math.ceil(angle / NODE_STEP_ANGLE))
    s_list = list(np.linspace(0.0, 1.0, count + 1))
    q_list = [np.asarray(q_start, dtype=float)]
    for s in s_list[1:]:
        q_list.append(solve_nearest(robot, frames, line.pose(s), q_list[-1], s))
    for _ in range(MAX_REFINEMENTS):
        s_arr = np.array(s_list)
        q_arr = np.stack(q_list)
        path = NodePath.through(s_arr, q_arr)
        mids = 0.5 * (s_arr[:-1] + s_arr[1:])
        pos_err, ang_err = _tool_errors(robot, frames, line, mids, path.q(mids))
        step = np.max(np.abs(np.diff(q_arr, axis=0)), axis=1)
        jumpy = step > JOINT_STEP_LIMIT
        bad = jumpy | (pos_err > POSITION_TOLERANCE) | (ang_err > ANGLE_TOLERANCE)
        if not np.any(bad):
            return path
        first_bad = float(mids[np.flatnonzero(bad)[0]])
        widths = np.diff(s_arr)
        tiny = (widths * length <= MIN_NODE_LENGTH) & (widths * angle <= MIN_NODE_ANGLE)
        if np.any(jumpy & tiny):
            i = int(np.flatnonzero(jumpy & tiny)[0])
            _explain_limit(robot, frames, line, float(s_arr[i + 1]), q_arr[i])
            joint = int(np.argmax(np.abs(q_arr[i + 1] - q_arr[i])))
            raise PlanRefused(
                RefusalReason.JOINT_JUMP,
                f"joint {joint + 1} would jump {math.degrees(step[i]):.1f} deg at {100 * mids[i]:.1f} % of the line "
                "(singularity or change of arm configuration)",
                at=float(mids[i]),
            )
        split = np.flatnonzero(bad & ~tiny)
        if split.size == 0:  # only the tolerance fails on intervals already at the finest spacing
            return path
        new_s, new_q = [s_list[0]], [q_list[0]]
        to_split = set(split.tolist())
        resolve_from: int | None = None
        for i in range(len(s_list) - 1):
            if i in to_split:
                sm = float(mids[i])
                new_s.append(sm)
                new_q.append(solve_nearest(robot, frames, line.pose(sm), q_list[i], sm))
                if jumpy[i] and resolve_from is None:
                    resolve_from = len(new_s)
            new_s.append(s_list[i + 1])
            new_q.append(q_list[i + 1])
        if resolve_from is not None:
            # the nodes after a jump may sit on the wrong branch: follow the arm again from here
            for j in range(resolve_from, len(new_s)):
                new_q[j] = solve_nearest(robot, frames, line.pose(new_s[j]), new_q[j - 1], new_s[j])
        s_list, q_list = new_s, new_q
    raise PlanRefused(
        RefusalReason.JOINT_JUMP,
        f"the line could not be followed smoothly near {100 * first_bad:.1f} % of it (near a singularity)",
        at=first_bad,
    )
