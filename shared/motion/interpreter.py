"""The interpreter: statements in, planned segments out, one statement at a time.

Thesis §4.5 splits the telerobot into a language interpreter, a coordinator (path planning) and
an executor; §4.3.7 gives the console's preview a simulator with the same interpreter and
planner. ``Interpreter`` is that interpreter and coordinator: it holds the state the statements
change (joint vector, speed setting, control mode, tool pose) and turns each statement into a
``Segment``, assuming the previous one ran to its end. The executor (preview or telerobot) plays
the segment and, when a motion stopped early (UNTIL) or a task ran, tells the interpreter where
the arm really is with ``resume_at``. Everything is deterministic: same inputs, same plan.

Tasks (``shared.language.tasks``) are run by the executor, not planned here: a TASK becomes a
zero-duration ``SegmentKind.TASK`` step. Its ``q_end`` is where the task's declared effect leaves
the arm (``shared.motion.task_effects.arm_end``, the function the robot's task code aims by):
where it was for grasp, ``EXTRACT_LIFT_M`` up the hole's axis for extract_peg, the held peg seated
in the hole for insert_peg, ``RELEASE_RETREAT_M`` back along the tool for release. The state
carries the objects as the plan has them (``TaskObjects``: a grasp holds, a release lets go), so
an insertion's seat follows from the grip the program's grasp made. After an ``unknown`` task
(insert_peg, whose exact end contact decides, or a task this registry does not know) no action and
no arm-moving task can be planned until ``resume_at``; insert_peg's ``q_end`` is still its
predicted seat when the grip is known (the robot reports the truth, within the effect's
tolerance), and the pose before it when not.

Speeds: ``SPEED`` sets the speed of the following actions; ``WITH SPEED`` replaces it for one
action. A fraction scales every velocity limit (joints, tool line, tool rotation); an absolute
speed (m/s for the tool point on DRAW/MOVES, rad/s for the tool's rotation on ROTATE/MOVES or for
every joint on MOVE/DRIVE) caps the motion at that value and the robot's limits, whichever is
lower; a unit an action cannot take (``shared.language.statements.ALLOWED_SPEED_UNITS``, the table the checks use) is
refused. Accelerations are always the robot's limits.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from shared.cells.cell import Cell, Feature
from shared.collision.interference import InterferenceZones, PathDetour, PathRefused
from shared.errors import InputError
from shared.language.bounds import MAX_MOTION_S
from shared.language.statements import (
    ALLOWED_SPEED_UNITS,
    SPEED_UNIT_TEXT,
    Draw,
    Drive,
    Event,
    Mode,
    Move,
    Moves,
    Rotate,
    SetMode,
    SetSpeed,
    Speed,
    SpeedUnit,
    Statement,
    TaskCall,
    UntilTime,
)
from shared.language.task_rule import UnknownPose, may_follow, pose_after, why_not
from shared.language.tasks import TASKS, ArmEnd, resolve_name
from shared.motion.frames import CellFrames
from shared.motion.limits import MotionLimits, default_limits
from shared.motion.paths import JointPath, NodePath, ToolLine, build_tool_path, hermite, solve_nearest
from shared.motion.profile import Trapezoid, evaluate_trapezoids
from shared.motion.refusal import PlanRefused, RefusalReason
from shared.motion.segment import Samples, Segment, SegmentKind
from shared.motion.task_effects import TaskObjects, arm_end
from shared.robots.ik import positions_tool_only
from shared.robots.model import LIMIT_TOLERANCE, Robot
from shared.spatial import rpy_to_matrix

log = logging.getLogger(__name__)

#: speed of actions before any SPEED statement: half the robot's maximum
DEFAULT_SPEED = Speed(value=0.5, unit=SpeedUnit.FRACTION)
#: a path shorter than this (rad of joint, m of tool, rad of tool rotation) is no motion
STILL = 1e-12


@dataclass(frozen=True)
class InterpreterState:
    """What the statements so far have set. ``world_T_tcp`` is the tool centre point at ``q``;
    ``index`` counts the statements planned; ``after_task`` names the last task whose end pose
    only the executor can know (see ``Interpreter.resume_at``), None when the pose is known;
    ``objects`` are the movable objects as the tasks so far left them (what the gripper holds)."""

    q: np.ndarray
    world_T_tcp: np.ndarray
    speed: Speed = DEFAULT_SPEED
    mode: Mode = Mode.POSITION
    index: int = 0
    unknown: UnknownPose | None = None
    objects: TaskObjects = field(default_factory=TaskObjects)

    @property
    def after_task(self) -> str | None:
        """The task after which the pose is unknown (``shared.language.task_rule``), or None."""
        return None if self.unknown is None else self.unknown.task


@dataclass(frozen=True)
class _Rates:
    """Velocity limits for one action after its speed is applied."""

    joint_velocity: np.ndarray
    linear: float
    angular: float
    warnings: tuple[str, ...] = ()


class Interpreter:
    """Plans statements one at a time for one robot in one cell."""

    def __init__(
        self,
        robot: Robot,
        q_start: Sequence[float] | np.ndarray,
        frames: CellFrames | None = None,
        limits: MotionLimits | None = None,
        features: dict[str, Feature] | None = None,
        zones: InterferenceZones | None = None,
        objects: TaskObjects | None = None,
    ) -> None:
        """``objects``: the movable objects at the start and what the gripper holds
        (``TaskObjects.of_cell``, ``TaskObjects.of_world``); none known when omitted."""
        self.robot = robot
        self.zones = zones  # mechanical interference zones (seed 001); None: not checked
        self.frames = frames or CellFrames.identity()
        self.features = dict(features or {})  # named points of the cell (holes), for task contracts
        self.limits = limits or default_limits(robot)
        self.limits.check_robot(robot)
        q = robot.as_q(q_start)
        robot.check_limits(q)
        self._state = InterpreterState(q=q.copy(), world_T_tcp=self.frames.world_T_tcp(robot, q),
                                       objects=objects if objects is not None else TaskObjects())

    @classmethod
    def for_cell(
        cls,
        cell: Cell,
        q_start: Sequence[float] | np.ndarray | None = None,
        limits: MotionLimits | None = None,
        zones: InterferenceZones | None = None,
        objects: TaskObjects | None = None,
    ) -> "Interpreter":
        """``objects`` default to the cell's as its file places them, nothing held."""
        q = cell.q_home if q_start is None else q_start
        return cls(cell.robot, q, CellFrames.from_cell(cell), limits, cell.features, zones,
                   TaskObjects.of_cell(cell) if objects is None else objects)

    @property
    def state(self) -> InterpreterState:
        return self._state

    def resume_at(self, q: Sequence[float] | np.ndarray) -> None:
        """The arm is at ``q`` (after an early stop or a task): plan on from there."""
        qa = self.robot.as_q(q)
        self._state = replace(self._state, q=qa.copy(), world_T_tcp=self.frames.world_T_tcp(self.robot, qa), unknown=None)

    def restore(self, state: InterpreterState) -> None:
        """Plan on from ``state``, one this interpreter reported before (``state`` after some
        statement): the next statement is planned as it was then."""
        self._state = state

    # -- planning -----------------------------------------------------------------------------
    def plan_next(self, statement: Statement) -> Segment:
        """Plan ``statement`` from the current state and advance the state to its end.

        Raises ``PlanRefused`` (the state is then unchanged)."""
        state = self._state
        index = state.index
        try:
            if state.unknown is not None and not may_follow(statement, state.unknown):
                raise PlanRefused(RefusalReason.AFTER_TASK, why_not(statement, state.unknown))
            segment = self._plan(statement, state, index)
            _check_motion_time(segment)
        except PlanRefused as exc:
            raise exc.at_index(index) from None
        new_q = segment.q_end
        objects = state.objects
        if isinstance(statement, TaskCall):
            objects = self._objects_after(statement, state)
        self._state = replace(
            state,
            objects=objects,
            q=new_q.copy(),
            world_T_tcp=self.frames.world_T_tcp(self.robot, new_q) if segment.kind is not SegmentKind.PARAMETER else state.world_T_tcp,
            speed=statement.speed if isinstance(statement, SetSpeed) else state.speed,
            mode=statement.mode if isinstance(statement, SetMode) else state.mode,
            index=index + 1,
            unknown=pose_after(statement, index, state.unknown, segment.arm_end),  # type: ignore[arg-type]
        )
        for w in segment.warnings:
            log.info("statement %d (%s): %s", index + 1, statement.kind, w)
        return segment

    def _plan(self, st: Statement, state: InterpreterState, index: int) -> Segment:
        q0 = state.q.copy()  # segments never share arrays with the state
        if isinstance(st, SetSpeed):
            if st.speed.unit is SpeedUnit.FRACTION and st.speed.value > 1.0:
                raise PlanRefused(RefusalReason.INVALID, f"SPEED {100 * st.speed.value:g} % is above 100 %")
            return Segment(index, st, SegmentKind.PARAMETER, q0, q0, state.mode)
        if isinstance(st, SetMode):
            return Segment(index, st, SegmentKind.PARAMETER, q0, q0, st.mode)
        if isinstance(st, Event):
            return Segment(index, st, SegmentKind.PARAMETER, q0, q0, state.mode)
        if isinstance(st, TaskCall):
            return self._plan_task(st, state, index)
        if isinstance(st, (Move, Drive)):
            return self._plan_joint(st, state, index)
        if isinstance(st, (Draw, Rotate, Moves)):
            return self._plan_tool(st, state, index)
        raise InputError(f"statement kind {getattr(st, 'kind', type(st).__name__)!r} cannot be planned")

    def _plan_task(self, st: TaskCall, state: InterpreterState, index: int) -> Segment:
        """The task's declared effect (``shared.language.tasks.TaskEffect``) as its end pose,
        by the function the robot aims with (``shared.motion.task_effects.arm_end``)."""
        spec = TASKS.get(st.name) or TASKS.get(st.name.lower())
        q0 = state.q
        if spec is None:
            return Segment(index, st, SegmentKind.TASK, q0.copy(), q0.copy(), state.mode, arm_end="unknown")
        arm_end_kind: ArmEnd = spec.arm_end
        effect = spec.effect
        if effect.arm == "still" or (effect.arm in ("lift", "retreat") and effect.distance_m == 0.0):
            return Segment(index, st, SegmentKind.TASK, q0.copy(), q0.copy(), state.mode, arm_end=arm_end_kind)
        hole = resolve_name(st.args[1], tuple(self.features)) if len(st.args) > 1 else None
        grip = state.objects.grip
        if grip is not None and st.args and resolve_name(st.args[0], (grip.name,)) is None:
            grip = None  # the task names another object than the one held: no seat to predict
        target = arm_end(effect, state.world_T_tcp, None if hole is None else self.features[hole].world_T_feature,
                         grip, state.objects.depths.get(grip.name) if grip is not None else None)
        if target is None:  # no hole to move along or no known grip: only the robot will know
            return Segment(index, st, SegmentKind.TASK, q0.copy(), q0.copy(), state.mode, arm_end="unknown")
        try:
            q_end = solve_nearest(self.robot, self.frames, target, q0, 1.0)
        except PlanRefused:
            if effect.arm != "seat":
                raise
            # a seat the arm cannot reach: the robot will fail or find it; the plan does not guess
            return Segment(index, st, SegmentKind.TASK, q0.copy(), q0.copy(), state.mode, arm_end="unknown")
        return Segment(index, st, SegmentKind.TASK, q0.copy(), q_end, state.mode, arm_end=arm_end_kind)

    def _objects_after(self, st: TaskCall, state: InterpreterState) -> TaskObjects:
        """The objects after the task ``st``: its effect on them, the tool where the gripper
        closed or opened (a release lets go before it retreats)."""
        spec = TASKS.get(st.name) or TASKS.get(st.name.lower())
        if spec is None:
            return state.objects
        return state.objects.after(spec.effect, tuple(st.args), state.world_T_tcp)

    def _rates(self, st: Move | Drive | Draw | Rotate | Moves, state: InterpreterState) -> _Rates:
        lim = self.limits
        speed = st.speed if st.speed is not None else state.speed
        if speed.unit not in ALLOWED_SPEED_UNITS[st.kind]:
            via = "WITH SPEED" if st.speed is not None else "the SPEED setting"
            takes = " or ".join(SPEED_UNIT_TEXT[u] for u in ALLOWED_SPEED_UNITS[st.kind])
            raise PlanRefused(RefusalReason.INVALID, f"{st.kind} cannot take {via} in {SPEED_UNIT_TEXT[speed.unit]}; it takes {takes}")
        if speed.unit is SpeedUnit.FRACTION:
            if speed.value > 1.0:
                raise PlanRefused(RefusalReason.INVALID, f"speed {100 * speed.value:g} % is above 100 %")
            f = speed.value
            return _Rates(lim.joint_velocity * f, lim.linear_speed * f, lim.angular_speed * f)
        cap = speed.value
        if speed.unit is SpeedUnit.M_PER_S:  # DRAW, MOVES: the tool point's speed on the line
            warnings = () if cap <= lim.linear_speed else (
                f"{1e3 * cap:g} mm/s is above the robot's {1e3 * lim.linear_speed:g} mm/s; using that",
            )
            return _Rates(lim.joint_velocity, min(cap, lim.linear_speed), lim.angular_speed, warnings)
        if isinstance(st, (Move, Drive)):  # rad/s on a joint move: every joint's speed
            warnings = () if np.all(cap <= lim.joint_velocity) else (
                f"{math.degrees(cap):g} deg/s is above some joints' limits; those joints use their limits",
            )
            return _Rates(np.minimum(lim.joint_velocity, cap), lim.linear_speed, lim.angular_speed, warnings)
        warnings = () if cap <= lim.angular_speed else (  # ROTATE, MOVES: the tool's rotation
            f"{math.degrees(cap):g} deg/s is above the robot's {math.degrees(lim.angular_speed):g} deg/s; using that",
        )
        return _Rates(lim.joint_velocity, lim.linear_speed, min(cap, lim.angular_speed), warnings)

    def _time_law(self, path: JointPath | NodePath, rates: _Rates, v_s: float, a_s: float) -> Trapezoid:
        """Fastest trapezoid in ``s`` keeping every joint within ``rates`` and the acceleration
        limits: with ``|q'| <= d1`` and ``|q''| <= d2`` along the path, ``|qd| <= d1 sd`` and
        ``|qdd| <= d2 sd^2 + d1 |sdd|``."""
        d1, d2 = path.bounds()
        acc = self.limits.joint_acceleration
        moving = d1 > STILL
        curved = d2 > STILL
        with np.errstate(divide="ignore", invalid="ignore"):
            by_velocity = np.where(moving, rates.joint_velocity / d1, math.inf).min()
            by_curvature = np.where(curved, np.sqrt(acc / (2.0 * d2)), math.inf).min()
            v_s = min(v_s, float(by_velocity), float(by_curvature))
            a_s = min(a_s, float(np.where(moving, (acc - d2 * v_s * v_s) / d1, math.inf).min()))
        return Trapezoid(velocity=v_s, accel=a_s)

    def _plan_joint(self, st: Move | Drive, state: InterpreterState, index: int) -> Segment:
        robot = self.robot
        q0 = state.q
        if isinstance(st, Move):
            if len(st.joints) != robot.dof:
                raise PlanRefused(RefusalReason.INVALID, f"MOVE gives {len(st.joints)} joints; robot {robot.name!r} has {robot.dof}")
            q1 = np.array(st.joints, dtype=float)
        else:
            if st.joint > robot.dof:
                raise PlanRefused(RefusalReason.INVALID, f"DRIVE J{st.joint}: robot {robot.name!r} has joints J1..J{robot.dof}")
            q1 = q0.copy()
            q1[st.joint - 1] = st.target
        if not robot.within_limits(q1):
            i = int(np.flatnonzero((q1 < robot.lower - LIMIT_TOLERANCE) | (q1 > robot.upper + LIMIT_TOLERANCE))[0])
            raise PlanRefused(
                RefusalReason.JOINT_LIMIT,
                f"J{i + 1} target {math.degrees(q1[i]):.3f} deg is outside its range "
                f"[{math.degrees(robot.lower[i]):.3f}, {math.degrees(robot.upper[i]):.3f}] deg",
            )
        rates = self._rates(st, state)
        path: JointPath | NodePath = JointPath(q0.copy(), q1)
        kind = SegmentKind.JOINT
        if not np.any(np.abs(path.delta) > STILL):
            return Segment(index, st, kind, q0.copy(), q1, state.mode, warnings=rates.warnings)
        warnings = rates.warnings
        if self.zones is not None:
            check = self.zones.check_path(q0, q1)
            if isinstance(check, PathRefused):
                raise PlanRefused(RefusalReason.INTERFERENCE, f"{check.reason}")
            if isinstance(check, PathDetour):
                path = _detour_path(q0, list(check.waypoints), q1)
                warnings += (f"detoured round interference zone(s) {', '.join(check.zones)} through {len(check.waypoints)} waypoint(s)",)
        v_s = a_s = math.inf
        law = self._time_law(path, rates, v_s, a_s)
        return Segment(index, st, kind, q0.copy(), q1, state.mode, path, law, warnings)

    def _goal(self, st: Draw | Rotate | Moves, state: InterpreterState) -> np.ndarray:
        world_T_start = state.world_T_tcp
        world_T_frame = self.frames.world_T_frame(st.frame, world_T_start)
        goal = world_T_start.copy()
        if isinstance(st, (Draw, Moves)):
            goal[:3, 3] = world_T_frame[:3, :3] @ np.asarray(st.position, dtype=float) + world_T_frame[:3, 3]
        if isinstance(st, (Rotate, Moves)):
            goal[:3, :3] = world_T_frame[:3, :3] @ rpy_to_matrix(np.asarray(st.rpy, dtype=float))
        return goal

    def _plan_tool(self, st: Draw | Rotate | Moves, state: InterpreterState, index: int) -> Segment:
        robot = self.robot
        if positions_tool_only(robot):
            if isinstance(st, (Rotate, Moves)):
                raise PlanRefused(RefusalReason.UNSUPPORTED, f"robot {robot.name!r} places its tool point only; it cannot {st.kind}")
            if np.linalg.norm(self.frames.tool_T_tcp[:3, 3]) > STILL:
                raise PlanRefused(
                    RefusalReason.UNSUPPORTED,
                    f"robot {robot.name!r} places its tool point only, so a DRAW needs the cell's tcp at that point",
                )
        rates = self._rates(st, state)
        line = ToolLine(state.world_T_tcp, self._goal(st, state))
        length, angle = line.length, line.angle
        if positions_tool_only(robot):
            angle = 0.0
        q0 = state.q
        if length <= STILL and angle <= STILL:
            return Segment(index, st, SegmentKind.CARTESIAN, q0.copy(), q0.copy(), state.mode, warnings=rates.warnings)
        path = build_tool_path(robot, self.frames, q0, line)
        v_s = a_s = math.inf
        if length > STILL:
            v_s = min(v_s, rates.linear / length)
            a_s = min(a_s, self.limits.linear_acceleration / length)
        if angle > STILL:
            v_s = min(v_s, rates.angular / angle)
            a_s = min(a_s, self.limits.angular_acceleration / angle)
        law = self._time_law(path, rates, v_s, a_s)
        return Segment(index, st, SegmentKind.CARTESIAN, q0.copy(), path.q_end.copy(), state.mode, path, law, rates.warnings)


@dataclass(frozen=True)
class Plan:
    """A program planned from ``q_start``: one segment per statement up to the first refusal.

    ``refusal`` is None when every statement was planned. A TASK segment has zero duration here:
    how long a task takes is known only when the executor runs it.
    """

    segments: tuple[Segment, ...]
    q_start: np.ndarray
    q_final: np.ndarray
    refusal: PlanRefused | None = None
    start_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    after_task: str | None = None
    """A task whose exact end only the robot knows: ``q_final`` is its predicted end (insert_peg
    with a known grip) or the pose before it, and nothing that moves the arm was planned after it."""

    @classmethod
    def of(cls, segments: Sequence[Segment], q_start: np.ndarray, end: InterpreterState,
           refusal: PlanRefused | None, durations: Sequence[float] | None = None) -> "Plan":
        """The plan of ``segments``, planned in order from ``q_start`` to the interpreter state
        ``end``, stopped by ``refusal`` (None: every statement planned). ``durations``: the
        segments' durations when the caller keeps them (``PrefixPlanner``)."""
        durations = np.array([s.duration for s in segments] if durations is None else durations, dtype=float)
        starts = np.concatenate([[0.0], np.cumsum(durations)[:-1]]) if len(segments) else np.zeros(0)
        return cls(tuple(segments), q_start, end.q.copy(), refusal, starts, end.after_task)

    @property
    def ok(self) -> bool:
        return self.refusal is None

    def _sample_table(self) -> "_SampleTable":
        cached = self.__dict__.get("_table")
        if cached is None:
            cached = _build_sample_table(self.segments, self.q_start.size)
            object.__setattr__(self, "_table", cached)
        return cached

    @property
    def durations(self) -> np.ndarray:
        return np.array([s.duration for s in self.segments])

    @property
    def duration(self) -> float:
        return float(np.sum(self.durations))

    def sample(self, t: float | np.ndarray) -> Samples:
        """The whole program's trajectory at program times ``t`` (scalar or (n,), any order), in
        one vectorised pass over all segments (the preview samples whole plans at display rate)."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        dof = self.q_start.size
        q = np.empty((ts.size, dof))
        qd = np.zeros((ts.size, dof))
        qdd = np.zeros((ts.size, dof))
        if not self.segments:
            q[:] = self.q_start
            return Samples(ts, q, qd, qdd)
        # long requests in blocks: the temporaries stay in cache instead of growing with t
        for lo in range(0, ts.size, SAMPLE_BLOCK):
            hi = min(lo + SAMPLE_BLOCK, ts.size)
            q[lo:hi], qd[lo:hi], qdd[lo:hi] = self._sample_block(ts[lo:hi])
        return Samples(ts, q, qd, qdd)

    def _sample_block(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dof = self.q_start.size
        q = np.empty((ts.size, dof))
        qd = np.zeros((ts.size, dof))
        qdd = np.zeros((ts.size, dof))
        table = self._sample_table()
        # the last segment starting at or before t owns t (a zero-length segment owns only the
        # times after the whole plan, when it is among the last)
        owner = np.searchsorted(self.start_times, ts, side="right") - 1
        before = owner < 0
        k_all = np.maximum(owner, 0)
        code = np.where(before, _STILL, table.code[k_all])
        q[before] = self.q_start
        still = code == _STILL
        q[still & ~before] = table.q_end[k_all[still & ~before]]
        moving = ~still
        if np.any(moving):
            k = k_all[moving]
            s, sd, sdd = evaluate_trapezoids(ts[moving] - self.start_times[k], table.velocity[k], table.accel[k])
            joint = table.code[k] == _JOINT
            pos = np.empty((k.size, dof))
            d1 = np.empty((k.size, dof))
            d2 = np.zeros((k.size, dof))
            delta = table.q_end[k[joint]] - table.q_start[k[joint]]
            pos[joint] = table.q_start[k[joint]] + s[joint, None] * delta
            d1[joint] = delta
            line = ~joint
            if np.any(line):
                kl, sl = k[line], s[line]
                # node interval: search on (2 * segment + s) so segments never share a key
                j = np.searchsorted(table.node_key, 2.0 * kl + sl, side="right") - 1
                j = np.clip(j, table.first[kl], table.last[kl] - 1)
                h = table.node_s[j + 1] - table.node_s[j]
                u = (sl - table.node_s[j]) / h
                args = (table.node_q[j], table.node_q[j + 1], table.node_m[j], table.node_m[j + 1], h, u)
                pos[line], d1[line], d2[line] = (hermite(*args, order) for order in (0, 1, 2))
            done = s >= 1.0
            pos[done] = table.q_end[k[done]]  # exact targets
            q[moving] = pos
            qd[moving] = d1 * sd[:, None]
            qdd[moving] = d2 * (sd * sd)[:, None] + d1 * sdd[:, None]
        return q, qd, qdd


_STILL, _JOINT, _LINE = 0, 1, 2
#: samples per block in ``Plan.sample``
SAMPLE_BLOCK = 8192


@dataclass(frozen=True)
class _SampleTable:
    """A plan's segments as flat arrays, so that sampling needs no loop over segments.

    ``code`` per segment: still (no timed motion), joint line, or node path; ``velocity`` and
    ``accel`` its time law; node arrays concatenate every node path, segment ``k`` owning nodes
    ``first[k] .. last[k]`` with search keys ``2 k + s``."""

    code: np.ndarray
    velocity: np.ndarray
    accel: np.ndarray
    q_start: np.ndarray
    q_end: np.ndarray
    first: np.ndarray
    last: np.ndarray
    node_key: np.ndarray
    node_s: np.ndarray
    node_q: np.ndarray
    node_m: np.ndarray


def _build_sample_table(segments: tuple[Segment, ...], dof: int) -> _SampleTable:
    n = len(segments)
    code = np.full(n, _STILL)
    velocity = np.ones(n)
    accel = np.ones(n)
    q_start = np.stack([s.q_start for s in segments])
    q_end = np.stack([s.q_end for s in segments])
    first = np.zeros(n, dtype=int)
    last = np.ones(n, dtype=int)
    keys, node_s, node_q, node_m = [np.zeros(0)], [np.zeros(0)], [np.zeros((0, dof))], [np.zeros((0, dof))]
    count = 0
    for i, seg in enumerate(segments):
        if seg.law is None or seg.path is None or seg.duration <= 0.0:
            continue
        velocity[i], accel[i] = seg.law.velocity, seg.law.accel
        if isinstance(seg.path, NodePath):
            code[i] = _LINE
            m = seg.path.s_nodes.size
            first[i], last[i] = count, count + m - 1
            keys.append(2.0 * i + seg.path.s_nodes)
            node_s.append(seg.path.s_nodes)
            node_q.append(seg.path.q_nodes)
            node_m.append(seg.path.tangents)
            count += m
        else:
            code[i] = _JOINT
    return _SampleTable(
        code, velocity, accel, q_start, q_end, first, last,
        np.concatenate(keys), np.concatenate(node_s), np.concatenate(node_q), np.concatenate(node_m),
    )


def _check_motion_time(segment: Segment) -> None:
    """Refuse a motion planned to take longer than ``MAX_MOTION_S`` (a working day): a long line
    at the slowest speed the language allows. A motion cut short by ``UNTIL TIME`` counts until then."""
    until = segment.until
    end = min(segment.duration, until.seconds) if isinstance(until, UntilTime) else segment.duration
    if not end <= MAX_MOTION_S:
        raise PlanRefused(
            RefusalReason.INVALID,
            f"{segment.statement.kind} would take {end / 3600.0:.3g} h at its speed: longer than the "
            f"{MAX_MOTION_S / 3600.0:g} h bound on one motion; give it a higher speed",
        )


def _detour_path(q0: np.ndarray, waypoints: list[np.ndarray], q1: np.ndarray) -> NodePath:
    """The polyline ``q0 -> waypoints -> q1`` as a path that stops at every corner: Hermite pieces
    with zero tangents stay on each straight leg (so they never cut a zone's corner) and the
    velocity along the path is continuous."""
    nodes = np.vstack([q0, *waypoints, q1])
    legs = np.linalg.norm(np.diff(nodes, axis=0), axis=1)
    keep = np.concatenate([[True], legs > STILL])
    nodes = nodes[keep]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(nodes, axis=0), axis=1))])
    return NodePath(s / s[-1], nodes, np.zeros_like(nodes))


def plan_program(
    program: Sequence[Statement],
    robot: Robot,
    cell: Cell | None = None,
    start_q: Sequence[float] | np.ndarray | None = None,
    limits: MotionLimits | None = None,
    zones: InterferenceZones | None = None,
    objects: TaskObjects | None = None,
) -> Plan:
    """Plan every statement of ``program`` in order, stopping at the first refusal.

    ``start_q`` defaults to the cell's home pose, or (no cell) to zero clipped into the joint
    ranges. ``objects``: the movable objects at the start and the grip (default: the cell's as
    loaded, nothing held). Raises ``InputError`` only for a bad start or a cell for another robot.
    """
    if cell is not None and cell.robot.name != robot.name:
        raise InputError(f"cell {cell.name!r} holds robot {cell.robot.name!r}, not {robot.name!r}")
    if start_q is None:
        start_q = cell.q_home if cell is not None else np.clip(np.zeros(robot.dof), robot.lower, robot.upper)
    frames = CellFrames.from_cell(cell) if cell is not None else CellFrames.identity()
    if objects is None and cell is not None:
        objects = TaskObjects.of_cell(cell)
    interp = Interpreter(robot, start_q, frames, limits, cell.features if cell is not None else None, zones, objects)
    q_start = interp.state.q.copy()
    segments: list[Segment] = []
    refusal: PlanRefused | None = None
    for statement in program:
        try:
            segments.append(interp.plan_next(statement))
        except PlanRefused as exc:
            refusal = exc
            break
    return Plan.of(segments, q_start, interp.state, refusal)
