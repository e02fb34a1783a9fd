"""Side by side: what the console predicted for a submitted range, and what the robot reported.

The plan (``records.PlannedPath``) runs on plan time from the range's start; the robot's
telemetry runs on the robot's clock. They are aligned at the first frame that names one of the
range's statements: that frame's robot time is the plan time at which that statement starts. Then
for every frame while the range ran:

* the tool point the robot reported (its base frame, carried into the world by the cell's
  ``world_T_base``) against the planned tool point at the same plan time: the largest distance is
  how far the robot was from where the console said it would be *then*;
* the same reported point against the whole planned path (the nearest point of its polyline):
  how far the robot left the planned *path*, whatever the timing;
* each statement's end on both clocks: the largest difference is how much earlier or later than
  planned a statement finished.

Pure computation: numpy over the recorded payloads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from server.recording import records
from server.recording.reader import Recording


PATH_FOLLOWED_M = 0.005
"""A robot within this of the planned path followed it (a gap at the same time beyond it is timing)."""


@dataclass(frozen=True)
class StatementTiming:
    number: int
    text: str
    planned_end_s: float
    """plan time the statement ends, s from the range's start"""
    reported_end_s: float
    """when the robot's frames stop naming it, on the same axis"""

    @property
    def late_s(self) -> float:
        return self.reported_end_s - self.planned_end_s


@dataclass(frozen=True)
class RangeComparison:
    """One submitted range, planned against reported."""

    index: int
    """which submitted range of the recording (0: the first)"""
    submitted_ns: int
    texts: list[str]
    numbers: list[int | None]
    planned_world_p_tool: np.ndarray
    """(n, 3) m, the console's plan"""
    reported_world_p_tool: np.ndarray
    """(m, 3) m, the robot's frames while the range ran (may be empty)"""
    reported_plan_t: np.ndarray
    """(m,) s: each frame's time on the plan's axis"""
    largest_gap_m: float | None
    """largest distance between reported and planned tool points at the same time"""
    largest_gap_at_s: float | None
    largest_gap_points: tuple[np.ndarray, np.ndarray] | None
    """(planned, reported) world points of that largest gap"""
    largest_path_gap_m: float | None
    """largest distance from a reported point to the planned path (any time)"""
    timings: list[StatementTiming]
    complete_plan: bool
    problem: str | None = None
    """why there is nothing (or less) to compare, in a sentence"""

    @property
    def largest_time_gap(self) -> StatementTiming | None:
        return max(self.timings, key=lambda s: abs(s.late_s)) if self.timings else None

    def gap_explained(self) -> str | None:
        """What the two gaps together say, in a sentence: a gap at the same time with the robot on
        the planned path is timing (it ran ahead of or behind the plan: force-guided moves and tasks
        take the time their contact takes), not a deviation; a gap from the path is where it went
        elsewhere. None when there is nothing to compare."""
        at_time, from_path = self.largest_gap_m, self.largest_path_gap_m
        if at_time is None or from_path is None:
            return None
        if from_path <= PATH_FOLLOWED_M and at_time > PATH_FOLLOWED_M:
            return (f"the robot stayed within {1e3 * PATH_FOLLOWED_M:.0f} mm of the planned path: the gap at the same "
                    f"time is timing, not a deviation (it was ahead of or behind the plan; force-guided moves and "
                    f"tasks take the time their contact takes)")
        if from_path > PATH_FOLLOWED_M:
            return (f"the robot left the planned path by up to {1e3 * from_path:.1f} mm (a task's own motion, a "
                    f"compliant correction, or a stop): see where on the timeline")
        return "the robot followed the plan in place and in time"

    def lines(self) -> list[str]:
        """The comparison in sentences (the replay page shows them)."""
        out = [f"Range {self.index + 1}: " + "; ".join(self.texts)]
        if self.problem:
            out.append(self.problem)
        if self.largest_gap_m is not None:
            out.append(f"largest gap at the same time: {1e3 * self.largest_gap_m:.1f} mm at {self.largest_gap_at_s:.2f} s")
        if self.largest_path_gap_m is not None:
            out.append(f"largest gap from the planned path: {1e3 * self.largest_path_gap_m:.1f} mm")
        if (why := self.gap_explained()) is not None:
            out.append(why)
        worst = self.largest_time_gap
        if worst is not None:
            when = "later" if worst.late_s >= 0 else "earlier"
            out.append(f"largest time gap: #{worst.number} `{worst.text}` ended {abs(worst.late_s):.2f} s {when} "
                       f"than planned ({worst.reported_end_s:.2f} s against {worst.planned_end_s:.2f} s)")
        if not self.complete_plan:
            out.append("the plan does not cover the whole range (a refusal, or a task only the robot can end)")
        return out


def _numbers(recording: Recording) -> dict[int, int]:
    """Console id -> the robot's statement number, from the recorded statuses."""
    out: dict[int, int] = {}
    for m in recording.on(records.STATUS):
        if m.data.get("number") is not None:
            out[m.data["id"]] = m.data["number"]
    return out


def _distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """For each of ``points`` (m, 3) the distance to the polyline (n, 3), vectorised."""
    if len(polyline) == 1:
        return np.linalg.norm(points - polyline[0], axis=1)
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    length2 = np.einsum("ij,ij->i", ab, ab)
    ap = points[:, None, :] - a[None, :, :]
    s = np.clip(np.einsum("mij,ij->mi", ap, ab) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    nearest = a[None, :, :] + s[..., None] * ab[None, :, :]
    return np.linalg.norm(points[:, None, :] - nearest, axis=2).min(axis=1)


def compare_ranges(recording: Recording, world_T_base: np.ndarray) -> list[RangeComparison]:
    """Every submitted range of ``recording`` with a plan, compared (see the module docstring)."""
    world_T_base = np.asarray(world_T_base, dtype=float)
    numbers = _numbers(recording)
    frames = [(m.log_time_ns, m.data) for m in recording.on(records.TELEMETRY)]
    robot_t = np.array([f["robot_time"] for _, f in frames], dtype=float)
    statement = np.array([f["statement"] for _, f in frames], dtype=np.int64)
    base_p = np.array([f["base_p_tool"] for _, f in frames], dtype=float).reshape(-1, 3)
    world_p = base_p @ world_T_base[:3, :3].T + world_T_base[:3, 3] if len(base_p) else base_p
    out = []
    for index, m in enumerate(recording.on(records.SUBMITTED)):
        sub = records.RangeSubmitted.model_validate(m.data)
        nums = [numbers.get(i) for i in sub.ids]
        out.append(_compare(index, m.log_time_ns, sub, nums, robot_t, statement, world_p, frames))
    return out


def _compare(index, submitted_ns, sub, nums, robot_t, statement, world_p, frames) -> RangeComparison:
    empty = np.zeros((0, 3))
    base = dict(index=index, submitted_ns=submitted_ns, texts=sub.texts, numbers=nums)
    if sub.plan is None or not sub.plan.t:
        return RangeComparison(**base, planned_world_p_tool=empty, reported_world_p_tool=empty,
                               reported_plan_t=np.zeros(0), largest_gap_m=None, largest_gap_at_s=None,
                               largest_gap_points=None, largest_path_gap_m=None, timings=[], complete_plan=False,
                               problem="the console had no plan of this range (its start was unknown)")
    plan = sub.plan
    plan_t = np.asarray(plan.t, dtype=float)
    plan_p = np.asarray(plan.world_p_tool, dtype=float).reshape(-1, 3)
    after = np.array([t >= submitted_ns for t, _ in frames], dtype=bool)
    known = [(j, n) for j, n in enumerate(nums) if n is not None]
    mine = after & np.isin(statement, [n for _, n in known]) if known else np.zeros(len(frames), dtype=bool)
    rows = np.flatnonzero(mine)
    if not len(rows):
        return RangeComparison(**base, planned_world_p_tool=plan_p, reported_world_p_tool=empty,
                               reported_plan_t=np.zeros(0), largest_gap_m=None, largest_gap_at_s=None,
                               largest_gap_points=None, largest_path_gap_m=None, timings=[],
                               complete_plan=plan.complete,
                               problem="no telemetry frame names a statement of this range (never run, or not recorded)")
    first = rows[0]
    j_first = next(j for j, n in known if n == statement[first])
    offset = robot_t[first] - plan.statement_starts[j_first]  # robot time at plan time 0
    span = np.arange(first, rows[-1] + 1)
    reported = world_p[span]
    tau = robot_t[span] - offset
    tau_clamped = np.clip(tau, plan_t[0], plan_t[-1])
    planned_then = np.stack([np.interp(tau_clamped, plan_t, plan_p[:, k]) for k in range(3)], axis=1)
    gaps = np.linalg.norm(reported - planned_then, axis=1)
    worst = int(np.argmax(gaps))
    path_gap = float(_distance_to_polyline(reported, plan_p).max())
    timings = []
    for j, n in known:
        named = np.flatnonzero(statement[span] == n)
        if not len(named):
            continue
        last = span[named[-1]]
        nxt = last + 1 if last + 1 < len(robot_t) else last  # the statement ended before the next frame
        timings.append(StatementTiming(number=n, text=sub.texts[j], planned_end_s=float(plan.statement_ends[j]),
                                       reported_end_s=float(robot_t[nxt] - offset)))
    return RangeComparison(
        **base, planned_world_p_tool=plan_p, reported_world_p_tool=reported, reported_plan_t=tau,
        largest_gap_m=float(gaps[worst]), largest_gap_at_s=float(tau[worst]),
        largest_gap_points=(planned_then[worst], reported[worst]), largest_path_gap_m=path_gap,
        timings=timings, complete_plan=plan.complete,
    )
