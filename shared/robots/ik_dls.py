"""Damped-least-squares inverse kinematics for robots without a closed form (URDF arms).

Why this shape: a numeric solver finds one solution per starting point, so several
deterministic starts (the caller's reference configuration first, then a fixed spread of
seeds over the joint ranges) collect the distinct solutions. Each start runs a
Levenberg-Marquardt iteration whose damping follows the squared error (Sugihara's rule:
large steps are damped far from the goal, almost none near it, so convergence ends quadratic
even close to singularities) and grows when a step fails to reduce the error. The solver
works on unbounded joint values and returns them folded into (-pi, pi]; the dispatcher
(``shared.robots.ik.solve_ik``) maps them into the joint ranges and sorts them.
"""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin

from shared.robots.model import Robot

#: pose error (m and rad, Euclidean norm of the 6-vector) below which a start has converged
TOLERANCE = 1e-11
#: iterations allowed per start (a refused step counts as one)
MAX_ITERATIONS = 150
#: number of spread seeds tried after ``q_ref``
SPREAD_SEEDS = 24
#: floor of the damping (squared metres/radians): keeps steps finite at singular points yet
#: stays below the smallest squared singular values met near the workspace boundary, where a
#: larger floor (1e-9 was tried) stalls convergence at the micrometre level
DAMPING_FLOOR = 1e-13
#: two solutions closer than this (rad, max-norm, modulo 2 pi) are the same solution
SAME_SOLUTION = 1e-5
#: a start is abandoned when its error has not halved over this many iterations
STALL_WINDOW = 20
#: halvings of a Gauss-Newton step tried before a fallback start is given up
LINE_SEARCH_HALVINGS = 20


def _wrap(q: np.ndarray) -> np.ndarray:
    out = np.pi - np.mod(np.pi - q, 2.0 * np.pi)
    return np.where(out <= -np.pi, out + 2.0 * np.pi, out)


@functools.lru_cache(maxsize=16)
def _spread(dof: int, lower: tuple[float, ...], upper: tuple[float, ...], count: int) -> np.ndarray:
    """Fixed seeds spread over the joint ranges (at most one turn wide per joint)."""
    lo = np.maximum(np.array(lower), -np.pi)
    hi = np.minimum(np.array(upper), np.pi)
    rng = np.random.default_rng(20261126)  # fixed: the same target always gives the same answer
    seeds = lo + rng.random((count, dof)) * (hi - lo)
    seeds.setflags(write=False)
    return seeds


def _log3_batch(rotations: np.ndarray) -> np.ndarray:
    """Rotation vectors of a stack of rotation matrices (k, 3, 3) -> (k, 3), in numpy; the rare
    rotations within a few degrees of a half turn go through pinocchio's careful ``log3``."""
    cos = np.clip((np.einsum("kii->k", rotations) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    skew = 0.5 * np.stack(
        [rotations[:, 2, 1] - rotations[:, 1, 2], rotations[:, 0, 2] - rotations[:, 2, 0], rotations[:, 1, 0] - rotations[:, 0, 1]],
        axis=1,
    )
    sin = np.sin(theta)
    small = theta < 1e-4
    factor = np.where(small, 1.0 + theta**2 / 6.0, theta / np.where(small, 1.0, sin))
    out = skew * factor[:, None]
    for k in np.flatnonzero(cos < -0.998):  # theta above ~176 deg: sin too small to divide by
        out[k] = pin.log3(rotations[k])
    return out


def _pose_errors(robot: Robot, data: pin.Data, qs: np.ndarray, base_R_goal: np.ndarray, base_p_goal: np.ndarray) -> np.ndarray:
    """``[p_goal - p, log(R_goal R^T)]`` in base axes (m, rad) for each row of ``qs``: (k, 6)."""
    model, frame = robot.model, robot.tool_frame_id
    positions = np.empty((len(qs), 3))
    rotations = np.empty((len(qs), 3, 3))
    for k, q in enumerate(qs):
        pin.forwardKinematics(model, data, q)
        base_T_tool = pin.updateFramePlacement(model, data, frame)
        positions[k] = base_T_tool.translation
        rotations[k] = base_T_tool.rotation
    out = np.empty((len(qs), 6))
    out[:, :3] = base_p_goal - positions
    out[:, 3:] = _log3_batch(base_R_goal @ rotations.transpose(0, 2, 1))
    return out


def _jacobians(robot: Robot, data: pin.Data, qs: np.ndarray) -> np.ndarray:
    """Tool Jacobians (v, omega in base axes) for each row of ``qs``: (k, 6, dof)."""
    model, frame = robot.model, robot.tool_frame_id
    out = np.empty((len(qs), 6, robot.dof))
    for k, q in enumerate(qs):
        pin.computeJointJacobians(model, data, q)
        out[k] = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
    return out


class _Starts:
    """Every seed's joint vector, pose error and cost (``|e|^2 / 2``) while a batch descends
    toward one goal; which starts are still running and which have converged."""

    def __init__(self, robot: Robot, data: pin.Data, seeds: np.ndarray, base_R_goal: np.ndarray, base_p_goal: np.ndarray) -> None:
        self._robot, self._data = robot, data
        self._goal = (base_R_goal, base_p_goal)
        self.q = np.array(seeds, dtype=float)
        self.err, self.cost = self._evaluate(self.q)
        self.alive = np.ones(len(self.q), dtype=bool)
        self.converged = np.zeros(len(self.q), dtype=bool)

    def _evaluate(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        err = _pose_errors(self._robot, self._data, qs, *self._goal)
        return err, 0.5 * np.einsum("ij,ij->i", err, err)

    def running(self) -> np.ndarray:
        """Mark the starts within ``TOLERANCE`` converged; the indices of those still running."""
        done = self.alive & (np.sqrt(2.0 * self.cost) < TOLERANCE)
        self.converged |= done
        self.alive &= ~done
        return np.flatnonzero(self.alive)

    def normal_equations(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``J^T J`` (k, dof, dof) and ``J^T e`` (k, dof, 1) of the starts ``idx``."""
        jac = _jacobians(self._robot, self._data, self.q[idx])
        jac_t = jac.transpose(0, 2, 1)
        return jac_t @ jac, jac_t @ self.err[idx][:, :, None]

    def take_better(self, idx: np.ndarray, q_try: np.ndarray) -> np.ndarray:
        """Move each start ``idx`` to its row of ``q_try`` if that lowers its cost; which did."""
        err_try, cost_try = self._evaluate(q_try)
        better = cost_try < self.cost[idx]
        took = idx[better]
        self.q[took], self.err[took], self.cost[took] = q_try[better], err_try[better], cost_try[better]
        return better

    def result(self) -> np.ndarray:
        """The joint vectors, NaN rows for the starts that did not reach the goal (a start still
        running counts if it is within 100 ``TOLERANCE``)."""
        converged = self.converged | (self.alive & (np.sqrt(2.0 * self.cost) < 100.0 * TOLERANCE))
        q = self.q.copy()
        q[~converged] = np.nan
        return q


def _solve_batch(
    robot: Robot, data: pin.Data, seeds: np.ndarray, base_R_goal: np.ndarray, base_p_goal: np.ndarray
) -> np.ndarray:
    """Levenberg-Marquardt from every seed at once (lock-step, so the linear algebra is one
    batched numpy call per iteration). Returns the final joint vectors, one row per seed,
    with NaN rows for the seeds that did not reach the goal.

    Per start: damping ``boost * (cost + DAMPING_FLOOR)`` with ``cost = |e|^2 / 2``; a step that
    does not lower the cost is refused and ``boost`` grows tenfold, an accepted one shrinks it.
    A start is dropped when ``boost`` explodes (a local minimum) or its error has not halved over
    ``STALL_WINDOW`` iterations (an unreachable goal)."""
    starts = _Starts(robot, data, seeds, base_R_goal, base_p_goal)
    eye = np.eye(robot.dof)
    boost = np.ones(len(starts.q))
    history = [starts.cost.copy()]
    for _ in range(MAX_ITERATIONS):
        idx = starts.running()
        if idx.size == 0:
            break
        normal, rhs = starts.normal_equations(idx)
        damping = boost[idx] * (starts.cost[idx] + DAMPING_FLOOR)
        better = starts.take_better(idx, starts.q[idx] + _solve_steps(normal + damping[:, None, None] * eye, rhs))
        took, refused = idx[better], idx[~better]
        boost[took] = np.maximum(boost[took] * 0.3, 1.0)
        boost[refused] *= 10.0
        starts.alive[refused[boost[refused] > 1e12]] = False  # no descent direction left
        history.append(starts.cost.copy())
        if len(history) > STALL_WINDOW:  # cost is squared: 0.25 means the error halved
            starts.alive &= ~((starts.cost > 0.25 * history[-STALL_WINDOW - 1]) & (starts.cost > 1e-12))
    return starts.result()


def _gauss_newton_batch(
    robot: Robot, data: pin.Data, seeds: np.ndarray, base_R_goal: np.ndarray, base_p_goal: np.ndarray
) -> np.ndarray:
    """Undamped Gauss-Newton with a halving line search from every seed; rows as
    :func:`_solve_batch` returns them (NaN where the goal was not reached).

    The fallback for poses close to (not on) a singularity. There the smallest singular value of
    the Jacobian is tiny, Levenberg-Marquardt's damping stays far above its square, and a start
    creeps into a valley a few tens of micrometres from the goal and stalls. The plain
    Gauss-Newton direction keeps the weak direction; the line search tames its length."""
    starts = _Starts(robot, data, seeds, base_R_goal, base_p_goal)
    eye = np.eye(robot.dof)
    for _ in range(MAX_ITERATIONS):
        idx = starts.running()
        if idx.size == 0:
            break
        normal, rhs = starts.normal_equations(idx)
        step = _solve_steps(normal + DAMPING_FLOOR * eye, rhs)
        pending, scale = np.arange(idx.size), 1.0  # positions in idx still without a lower cost
        for _ in range(LINE_SEARCH_HALVINGS):
            better = starts.take_better(idx[pending], starts.q[idx[pending]] + scale * step[pending])
            pending = pending[~better]
            if pending.size == 0:
                break
            scale *= 0.5
        starts.alive[idx[pending]] = False  # no step along its direction lowers the error
    return starts.result()


def _solve_steps(lhs: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve the stacked systems ``lhs @ x = rhs`` ((k, n, n), (k, n, 1)) -> (k, n)."""
    try:
        return np.linalg.solve(lhs, rhs)[:, :, 0]
    except np.linalg.LinAlgError:  # numerically singular: least squares, row by row
        return np.stack([np.linalg.lstsq(a, b[:, 0], rcond=None)[0] for a, b in zip(lhs, rhs)])


def dls_ik_all(robot: Robot, base_T_tool: np.ndarray, q_ref: np.ndarray) -> list[np.ndarray]:
    """Every distinct joint vector (rad, folded into (-pi, pi]) that the starts reached for the
    tool pose ``base_T_tool`` (4, 4); the one reached from ``q_ref`` first. Empty if none."""
    base_T_tool = np.asarray(base_T_tool, dtype=float)
    base_R_goal = np.ascontiguousarray(base_T_tool[:3, :3])
    base_p_goal = np.ascontiguousarray(base_T_tool[:3, 3])
    data = robot.new_data()
    spread = _spread(robot.dof, tuple(robot.lower), tuple(robot.upper), SPREAD_SEEDS)
    seeds = np.vstack([np.asarray(q_ref, dtype=float), spread])
    reached = _solve_batch(robot, data, seeds, base_R_goal, base_p_goal)
    if np.isnan(reached[:, 0]).all():  # none: perhaps close to a singularity (see the fallback)
        reached = _gauss_newton_batch(robot, data, seeds, base_R_goal, base_p_goal)
    reached = _wrap(reached[~np.isnan(reached[:, 0])])
    # keep the first of every group of starts that reached the same solution (modulo 2 pi)
    apart = np.max(np.abs(_wrap(reached[:, None, :] - reached[None, :, :])), axis=2) >= SAME_SOLUTION
    keep = np.all(apart | ~np.tri(len(reached), k=-1, dtype=bool), axis=1)
    return list(reached[keep])
