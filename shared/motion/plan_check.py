"""Checking a plan before anything moves: collisions and joint limits along a range of its
statements, sampled in time (thesis §4.3: the preview warns before the operator sends).

``check_plan(plan, robot, collision, start, stop)`` samples statements ``start..stop-1`` of a
``Plan`` at ``dt`` (at most ``max_samples`` samples; a longer range is sampled more coarsely)
and returns the range's time span and its issues: the planner's refusal, the first sample of
each statement that leaves a joint range, and the first sample of each touching pair per
statement. It is a pure function of its inputs: a preview keeps the answer and plays it by time.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from shared.errors import InputError, TeleprogError
from shared.motion.interpreter import Plan, plan_program
from shared.robots.model import LIMIT_TOLERANCE

log = logging.getLogger(__name__)

IssueKind = Literal["plan", "joint_limit", "collision"]



@dataclass(frozen=True)
class PlanIssue:
    """One thing wrong with a plan: when (s from the range's start), in which statement
    (0-based index in the program), what, and which two bodies touch (collisions only)."""

    t: float
    index: int
    kind: IssueKind
    message: str
    bodies: tuple[str, str] | None = None


@dataclass(frozen=True)
class PlanCheck:
    """A checked range of a plan: it starts at program time ``t0`` and lasts ``duration`` s."""

    plan: Plan
    start: int
    stop: int
    t0: float
    duration: float
    issues: tuple[PlanIssue, ...]
    refusal: str | None

    def statement_at(self, t: float) -> int:
        """The statement (0-based, within the range) playing at range time ``t``."""
        i = int(np.searchsorted(self.plan.start_times, self.t0 + t, side="right") - 1)
        return min(max(i, self.start), self.stop - 1)

    def q_at(self, t: float) -> np.ndarray:
        """The joint vector at range time ``t`` (clipped into the range)."""
        return self.plan.sample(self.t0 + min(max(t, 0.0), self.duration)).q[0]

    def statement_ends(self) -> list[float]:
        """Range times where each planned statement of the range ends."""
        p = self.plan
        return [float(p.start_times[i] + p.segments[i].duration - self.t0) for i in range(self.start, min(self.stop, len(p.segments)))]

    def statement_starts(self) -> list[float]:
        p = self.plan
        return [float(p.start_times[i] - self.t0) for i in range(self.start, min(self.stop, len(p.segments)))]


def check_plan(
    plan: Plan,
    robot,
    collision,
    start: int,
    stop: int,
    *,
    object_poses: Mapping[str, np.ndarray] | None = None,
    dt: float = 0.05,
    max_samples: int = 600,
) -> PlanCheck:
    """Check statements ``start..stop-1`` of ``plan`` (planned from the program's start) for
    the planner's refusal, joint limits (``robot``'s ranges) and collisions (``collision``: a
    ``shared.collision.cell_check.CellCollision``, objects at ``object_poses``)."""
    issues: list[PlanIssue] = []
    refusal = None
    if plan.refusal is not None:
        refusal = str(plan.refusal)
        idx = plan.refusal.index if plan.refusal.index is not None else len(plan.segments)
        issues.append(PlanIssue(t=0.0, index=idx, kind="plan", message=refusal))
    t0 = float(plan.start_times[start]) if start < len(plan.segments) else plan.duration
    # the range ends where statement ``stop`` begins: a plan of more statements is not sampled past it
    t_end = float(plan.start_times[stop]) if stop < len(plan.segments) else plan.duration
    duration = max(0.0, t_end - t0)
    if duration > 0:
        step = max(dt, duration / max_samples)
        ts = np.append(np.arange(0.0, duration, step), duration)
        qs = plan.sample(t0 + ts).q
        index = np.clip(np.searchsorted(plan.start_times, t0 + ts, side="right") - 1, start, stop - 1)
        outside = (qs < robot.lower - LIMIT_TOLERANCE) | (qs > robot.upper + LIMIT_TOLERANCE)
        seen: set[tuple] = set()
        data = collision.new_data()
        for k, (t, q) in enumerate(zip(ts, qs)):
            idx = int(index[k])
            if outside[k].any() and ("joint_limit", idx) not in seen:
                seen.add(("joint_limit", idx))
                joint = int(np.argmax(outside[k])) + 1
                issues.append(PlanIssue(t=float(t), index=idx, kind="joint_limit",
                                        message=f"statement {idx + 1}: joint {joint} leaves its range at t={t:.2f} s"))
            pairs, _ = collision.touching(q, object_poses=object_poses, data=data)
            for a, b in pairs:
                key = ("collision", idx, a, b)
                if key not in seen:
                    seen.add(key)
                    issues.append(PlanIssue(t=float(t), index=idx, kind="collision", bodies=(a, b),
                                            message=f"statement {idx + 1}: {a} touches {b} at t={t:.2f} s"))
    return PlanCheck(plan, start, stop, t0, duration, tuple(issues), refusal)


PLANNER_FAILURES = (ArithmeticError, ValueError, IndexError, np.linalg.LinAlgError)
"""What the planner raises when numbers it was given break it (an overflow, a NaN reaching an index)."""


def planner_failure(exc: BaseException, what: str) -> InputError:
    """The refusal for one of ``PLANNER_FAILURES`` raised while planning ``what`` (logged)."""
    log.warning("planning %s failed: %r", what, exc)
    return InputError(f"the statements cannot be planned: {type(exc).__name__}: {exc}")


def plan_or_refuse(statements, robot, cell, start_q: np.ndarray, objects=None) -> Plan:
    """``plan_program`` from ``start_q`` (``objects``: the movable objects and the grip at the
    start, ``shared.motion.task_effects.TaskObjects``; default the cell's as loaded); a numerical
    failure of the planner on what it was given (an overflow, a NaN reaching an index) is refused
    as ``InputError`` naming it, never raised as itself."""
    try:
        with np.errstate(all="ignore"):
            return plan_program(list(statements), robot, cell, start_q=start_q, objects=objects)
    except TeleprogError:
        raise
    except PLANNER_FAILURES as exc:
        raise planner_failure(exc, f"{len(statements)} statement(s)") from None
