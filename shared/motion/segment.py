"""One planned statement: a timed joint trajectory, or a zero-time step, and how to run it.

A ``Segment`` is pure data plus pure functions of time: ``sample(t)`` (vectorised) gives joint
positions, velocities and accelerations; ``run`` and ``stepper`` play it against a sensor model,
stopping early when the statement's ``UNTIL`` condition holds. The preview and the telerobot
call the same code, so what the operator saw is what the robot does.

Times given to ``sample`` are seconds since the segment's start. Sensor models receive
``t0 + t``, where ``t0`` is the segment's start on the caller's clock (for a planned program,
``Plan.start_times``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from shared.errors import InputError
from shared.language.statements import Mode, Statement, UntilContact, UntilForce, UntilTime
from shared.motion.paths import JointPath, NodePath
from shared.motion.profile import Trapezoid
from shared.motion.sensors import SensorModel

#: bisection steps used to place an early stop between two samples (dt / 2**N resolution)
STOP_BISECTIONS = 30
#: servo steps a stepper samples at once (one vectorised ``sample`` call instead of one per step)
STEP_CHUNK = 32


class SegmentKind(str, Enum):
    JOINT = "joint"  # MOVE, DRIVE: straight line in joint space
    CARTESIAN = "cartesian"  # DRAW, ROTATE, MOVES: straight tool line, slerped orientation
    PARAMETER = "parameter"  # SPEED, MODE, EVENT: zero duration, changes the interpreter state
    TASK = "task"  # TASK: not planned here; the executor runs the task


class StopReason(str, Enum):
    COMPLETED = "completed"  # the motion reached its end
    FORCE = "force"  # UNTIL FORCE: the force exceeded the threshold
    CONTACT = "contact"  # UNTIL CONTACT: the tool touched something
    TIME = "time"  # UNTIL TIME: the time ran out


@dataclass(frozen=True)
class Samples:
    """Trajectory samples: ``t`` (n,) seconds since the segment's start, ``q``, ``qd``, ``qdd``
    (n, dof) in rad, rad/s, rad/s^2."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


@dataclass(frozen=True)
class Outcome:
    """What happened when a segment was played: where it stopped and why.

    ``samples`` run from the start to the stop (the last one is the stop). An UNTIL FORCE or
    UNTIL CONTACT motion whose condition never held ends ``COMPLETED`` at its target; ``force``
    is the force measured at the stop for UNTIL FORCE motions.
    """

    reason: StopReason
    t_stop: float
    q_stop: np.ndarray
    samples: Samples
    force: float | None = None

    @property
    def stopped_early(self) -> bool:
        return self.reason is not StopReason.COMPLETED


@dataclass(frozen=True)
class StepResult:
    t: float  # since the segment's start
    q: np.ndarray
    qd: np.ndarray
    done: bool
    reason: StopReason | None  # set when done


@dataclass(frozen=True)
class Segment:
    """A planned statement (``index`` is its 0-based place in the program)."""

    index: int
    statement: Statement
    kind: SegmentKind
    q_start: np.ndarray
    q_end: np.ndarray
    mode: Mode
    path: JointPath | NodePath | None = None
    law: Trapezoid | None = None
    warnings: tuple[str, ...] = field(default_factory=tuple)
    arm_end: str | None = None  # TASK only: "still", "retract" or "unknown" (shared.language.tasks)

    @property
    def duration(self) -> float:
        return 0.0 if self.law is None else self.law.duration

    @property
    def until(self) -> UntilForce | UntilContact | UntilTime | None:
        return getattr(self.statement, "until", None)

    @property
    def event(self) -> str | None:
        return self.statement.name if self.statement.kind == "EVENT" else None  # type: ignore[union-attr]

    # -- kinematic samples --------------------------------------------------------------------
    def sample(self, t: float | np.ndarray) -> Samples:
        """Positions, velocities, accelerations at times ``t`` (scalar or (n,)), clamped to
        [0, duration]."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        dof = self.q_start.size
        if self.law is None or self.path is None:
            q = np.broadcast_to(self.q_end, (ts.size, dof)).copy()
            zeros = np.zeros((ts.size, dof))
            return Samples(ts, q, zeros, zeros.copy())
        s, sd, sdd = self.law.evaluate(ts)
        q, dq, ddq = self.path.q_dq_ddq(s)
        qd = dq * sd[:, None]
        qdd = ddq * (sd * sd)[:, None] + dq * sdd[:, None]
        # exact ends (no interpolation round-off at the targets)
        q[ts <= 0.0] = self.q_start
        q[ts >= self.duration] = self.q_end
        return Samples(ts, q, qd, qdd)

    def times(self, dt: float) -> np.ndarray:
        """Sample times 0, dt, 2 dt, ... and the end."""
        if not dt > 0.0:
            raise InputError(f"sample period must be positive, got {dt}")
        total = self.duration
        n = int(np.floor(total / dt + 1e-9))
        ts = np.arange(n + 1) * dt
        if total - ts[-1] > 1e-12:
            ts = np.append(ts, total)
        return ts

    # -- stop conditions ----------------------------------------------------------------------
    def _triggered(self, t: float, q: np.ndarray, sensors: SensorModel | None, t0: float) -> bool:
        until = self.until
        if isinstance(until, UntilForce):
            return _need(sensors).force(t0 + t, q) > until.newtons
        if isinstance(until, UntilContact):
            return bool(_need(sensors).contact(t0 + t, q))
        return False

    def _end_time(self) -> float:
        """When the motion ends without a sensor: at its end, or earlier by UNTIL TIME."""
        until = self.until
        if isinstance(until, UntilTime):
            return min(self.duration, until.seconds)
        return self.duration

    def _refine(self, lo: float, hi: float, sensors: SensorModel | None, t0: float) -> float:
        """First time in (lo, hi] at which the condition holds (it does not at lo, does at hi)."""
        for _ in range(STOP_BISECTIONS):
            mid = 0.5 * (lo + hi)
            if self._triggered(mid, self.sample(mid).q[0], sensors, t0):
                hi = mid
            else:
                lo = mid
        return hi

    def _outcome(self, reason: StopReason, t_stop: float, ts: np.ndarray, sensors: SensorModel | None, t0: float) -> Outcome:
        ts = np.append(ts[ts < t_stop], t_stop)
        samples = self.sample(ts)
        q_stop = samples.q[-1]
        force = None
        if isinstance(self.until, UntilForce):
            force = float(_need(sensors).force(t0 + t_stop, q_stop))
        return Outcome(reason, float(t_stop), q_stop.copy(), samples, force)

    def _condition_reason(self) -> StopReason:
        return StopReason.FORCE if isinstance(self.until, UntilForce) else StopReason.CONTACT

    def run(self, sensors: SensorModel | None = None, dt: float = 0.01, t0: float = 0.0) -> Outcome:
        """Play the segment at period ``dt`` until it ends or its UNTIL condition holds."""
        end = self._end_time()
        timed_out = end < self.duration
        ts = self.times(dt)
        ts = np.append(ts[ts < end], end)
        if isinstance(self.until, (UntilForce, UntilContact)):
            q = self.sample(ts).q
            for k, t in enumerate(ts):
                if self._triggered(float(t), q[k], sensors, t0):
                    t_stop = 0.0 if k == 0 else self._refine(float(ts[k - 1]), float(t), sensors, t0)
                    return self._outcome(self._condition_reason(), t_stop, ts, sensors, t0)
        return self._outcome(StopReason.TIME if timed_out else StopReason.COMPLETED, end, ts, sensors, t0)

    def stepper(self, sensors: SensorModel | None = None, dt: float = 0.01, t0: float = 0.0) -> "SegmentStepper":
        """Play the segment one sample at a time (the executor's servo loop)."""
        return SegmentStepper(self, sensors, dt, t0)


def _need(sensors: SensorModel | None) -> SensorModel:
    if sensors is None:
        raise InputError("an UNTIL FORCE or UNTIL CONTACT statement needs a sensor model")
    return sensors


class SegmentStepper:
    """Steps a segment at ``t = k dt``; each ``step()`` returns the next sample and whether the
    segment is over. Same stops, at the same times, as ``Segment.run`` with the same ``dt``."""

    def __init__(self, segment: Segment, sensors: SensorModel | None, dt: float, t0: float) -> None:
        if not dt > 0.0:
            raise InputError(f"sample period must be positive, got {dt}")
        self.segment = segment
        self.sensors = sensors
        self.dt = dt
        self.t0 = t0
        self._k = 0
        self._t_prev: float | None = None
        self._end = segment._end_time()
        self.result: StepResult | None = None
        self._chunk: Samples | None = None
        self._chunk_k = 0

    def _time(self, k: int) -> float:
        t = min(k * self.dt, self._end)
        return self._end if self._end - t <= 1e-12 else t

    def _sample(self, k: int) -> tuple[float, np.ndarray, np.ndarray]:
        """Step ``k``'s time and sample, from a batch sampled ``STEP_CHUNK`` steps at a time (a
        motion is sampled at the same times whether or not it ends early, so nothing is wasted
        but the rest of the last batch)."""
        i = k - self._chunk_k
        if self._chunk is None or not 0 <= i < self._chunk.t.size:
            ts = np.array([self._time(j) for j in range(k, k + STEP_CHUNK)])
            if ts[-1] >= self._end:  # nothing past the end
                ts = ts[: int(np.argmax(ts >= self._end)) + 1]
            self._chunk, self._chunk_k, i = self.segment.sample(ts), k, 0
        chunk = self._chunk
        return float(chunk.t[i]), chunk.q[i].copy(), chunk.qd[i].copy()

    @property
    def done(self) -> bool:
        return self.result is not None and self.result.done

    def step(self) -> StepResult:
        if self.result is not None and self.result.done:
            return self.result
        seg = self.segment
        t, q, qd = self._sample(self._k)
        self._k += 1
        guarded = isinstance(seg.until, (UntilForce, UntilContact))
        if guarded and seg._triggered(t, q, self.sensors, self.t0):
            t_stop = 0.0 if self._t_prev is None else seg._refine(self._t_prev, t, self.sensors, self.t0)
            stop = seg.sample(t_stop)
            self.result = StepResult(t_stop, stop.q[0], np.zeros_like(q), True, seg._condition_reason())
            return self.result
        self._t_prev = t
        if t >= self._end:
            reason = StopReason.TIME if self._end < seg.duration else StopReason.COMPLETED
            self.result = StepResult(t, q, np.zeros_like(q), True, reason)
        else:
            self.result = StepResult(t, q, qd, False, None)
        return self.result
