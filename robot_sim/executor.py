"""The telerobot's executor (thesis §4.5): statements in, joint servo out, one status per outcome.

Sans-I/O and clock-free: the service calls ``tick()`` once per servo period and the executor
advances its own time by ``dt``, so tests run it in virtual time and the real process runs the
very same code in real time. Each statement is planned when it starts, from where the arm really
is, by the interpreter the console's preview uses (``shared.motion``), and stepped sample by
sample against the simulated world's sensors.

Every statement ends in exactly one final state: ``done``, ``failed`` (with the reason and the
robot's state), ``skipped`` or ``aborted``. On anything unexpected (contact that no UNTIL asked
for, a force over the safety limit, a refused plan, a failed task step) the arm holds where it
is, the statement fails, and the robot waits in FAULT for the operator: ``resume`` goes on with
the next statement, ``abort`` flushes the buffer. A statement that raises anything at all while it
is planned or stepped (a number the planner cannot handle, an IK that fails) fails the same way,
with the error as its reason: no statement can end the process.

``stop`` holds in every state, and after it nothing starts until ``resume``, ``skip`` or ``abort``:

* RUNNING: the arm freezes mid-motion (STOPPED); ``resume`` continues the same motion, ``skip``
  drops it and goes on with the next statement, ``abort`` drops it and the buffer.
* IDLE, with or without queued statements: STOPPED, the queue held (a statement arriving after
  the stop waits too); ``resume`` lets the queue run again. ``skip`` has no current statement to
  drop there: it is refused and the robot stays STOPPED.
* FAULT: stays FAULT (already holding); the stop is acknowledged as applied.
* STOPPED: stays STOPPED (idempotent).

At most one statement starts per servo tick, and only from IDLE, so even a run of zero-duration
statements (EVENT, SPEED, MODE, grasp) cannot slip past a stop.

Contact recovery: a contact the collision core finds (arm against the table or the plate) is
never commanded: the arm holds at the last servo sample that was clear. A force contact of the
held peg stops where the force crossed the limit; a motion that starts in contact may go on as
long as the (noise-free) contact force stays under the larger of the limit and the force it
started with, so backing away, sliding along or lifting off runs, and pressing further fails at
once; clear of the contact the normal rules apply.

Tasks (``shared.language.tasks``) run as generators of small guarded motions, planned by the
same interpreter, aimed at the poses each task's declared effect names
(``shared.motion.task_effects.arm_end``, the function the console's planner predicts with, fed
here with the grip the robot senses): ``insert_peg`` approaches the hole, descends until contact,
searches around the contact point with the force sensor when the peg lands on the plate, then
seats the peg (its foot on the floor, the seat the effect names) and, on physics, brings the arm
over the tool again (the compliant wrist straight), so the arm ends at the seat and not where the
search left it; ``extract_peg`` pulls the peg out along the hole's axis by the effect's lift and
fails if it sticks; ``release`` opens and backs off by the effect's retreat (none for the §4.6
gripper).
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Generator, Iterator
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from shared.cells.cell import Cell
from shared.collision import SceneModel
from shared.errors import TeleprogError
from shared.language.statements import (
    Draw,
    Frame,
    Mode,
    SetMode,
    Speed,
    SpeedUnit,
    Statement,
    TaskCall,
    UntilContact,
    UntilForce,
)
from shared.language.tasks import find_task, resolve_name
from shared.motion import Interpreter, PlanRefused, Segment, SegmentKind, StopReason
from shared.motion.task_effects import Grip, TaskObjects, arm_end
from shared.spatial import matrix_to_rpy
from shared.terrain.cell import TERRAIN_OBJECT, has_terrain, load_cell_terrain
from shared.wire.messages import MAX_TEXT, ControlMode, HaltCause, RobotSnapshot, RobotState, StatementState
from robot_sim.settings import ExecutorSettings
from robot_sim.world import PegState, SimWorld

if TYPE_CHECKING:
    from robot_sim.physics.world import PhysicsWorld

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ExecutorEvent:
    """A status change of one numbered statement, with the robot's state at that moment."""

    number: int
    state: StatementState
    reason: str | None
    snapshot: RobotSnapshot


class StepFailure(TeleprogError):
    """Something the executor did not expect: the statement fails with this reason."""


_Runner = Generator[None, None, str | None]

_FOLLOW_GATE_RAD = 0.002
"""Joint error under which the flange cannot be ``following_error`` off (no kinematics needed)."""
SENSOR_INVALID = "the wrist force sensor's readings are invalid (dropout); the arm holds"
_FORCE_GROWTH_N = 1e-6
"""Growth of a start-in-contact force that counts as pressing further (N; the force is noise-free)."""
_PHYSICS_FORCE_GROWTH_N = 2.0
"""The same on physics, where a force at rest still rings by a newton or so as the servo settles."""


def _one_line(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return text[:300]


class Executor:
    """One arm, one buffer of numbered statements, stepped one servo period at a time."""

    def __init__(self, cell: Cell, world: "SimWorld | PhysicsWorld", settings: ExecutorSettings | None = None, q0: np.ndarray | None = None,
                 scene: SceneModel | None = None):
        """``scene``: the cell's collision model when the caller built it already (trials build it
        once for many robots); otherwise it is built here."""
        self.cell = cell
        self.robot = cell.robot
        self.world = world
        self.settings = settings or ExecutorSettings()
        self.dt = 1.0 / self.settings.servo_rate
        self.time = 0.0
        self.q = np.array(cell.q_home if q0 is None else q0, dtype=float)
        self.physical = bool(getattr(world, "physical", False))
        """The world is contact physics: the arm is where the servo got it, the sensors read the
        present (no pose can be asked about before it is reached)."""
        if self.physical:
            self.q = world.q
        self._setpoint: np.ndarray | None = None  # what the servo holds between motions (None: where the world stopped it)
        self._commanded = False  # a motion commanded the servo in this tick
        self._comply = np.zeros(6)  # compliance's offset of the tool point (m, rad; world axes)
        self._complying = False  # force mode or a force-compliant task: the tool gives way
        self._in_task = False
        self._holding_clear = False
        self.state = RobotState.IDLE
        self.mode = Mode.POSITION
        zones = None
        if self.settings.interference_zones and self.robot.dof >= 3:
            from shared.collision.interference import robot_zones

            zones = robot_zones(self.robot)
        self.interpreter = Interpreter.for_cell(cell, self.q, zones=zones)
        self._model_objects = TaskObjects.of_cell(cell)  # the seat depths the task effects name
        # The collision core watches the arm against the real cell on every servo step. Pegs are
        # left to the contact model above (their fit in a hole is finer than any mesh test), and
        # so is the gripper holding or closing on one.
        # a terrain (rover cells) is checked by its own tree: building the generic hierarchy over
        # tens of thousands of triangles took seconds at every start
        self._terrain = load_cell_terrain(cell).checker if self.settings.collision_checks and has_terrain(cell) else None
        exclude = (TERRAIN_OBJECT,) if self._terrain is not None else ()
        if not self.settings.collision_checks:
            self._scene = None
        else:
            self._scene = scene if scene is not None and not exclude else SceneModel.from_cell(cell, exclude=exclude)
        self._skip = tuple(
            (peg, other) for peg in world.pegs for other in ("plate", "table", f"link{self.robot.dof}", f"link{self.robot.dof - 1}")
        )
        self.queue: deque[tuple[int, Statement]] = deque()
        self.current: tuple[int, Statement] | None = None
        self._runner: _Runner | None = None
        self.wrench = np.zeros(6)
        self.sensor_ok = True  # the wrist sensor's last reading was valid
        self.own_fault: tuple[HaltCause, str] | None = None  # why the robot went to FAULT by itself, until taken
        self.hold_queue = False  # True while no console is connected: start nothing new
        self.halted: str | None = None  # why the robot stopped by itself (silence, internal error)
        self._events: list[ExecutorEvent] = []

    # -- inputs -------------------------------------------------------------------------------
    def enqueue(self, number: int, statement: Statement) -> None:
        self.queue.append((number, statement))

    def room(self) -> int:
        """Statements the buffer can still take."""
        return max(0, self.settings.max_queue - len(self.queue))

    @property
    def busy(self) -> bool:
        """Something runs or waits in the buffer."""
        return self.current is not None or bool(self.queue)

    def _hold(self) -> None:
        """The joint servo holds the arm where it is now (physics: the measured pose)."""
        if self.physical and self._holding_clear:
            self._holding_clear = False  # already holding the last pose the collision core passed
            return
        if self.physical:
            self.world.hold()
            self._setpoint = None
            self.q = self.world.q

    def stop(self) -> tuple[bool, str]:
        if self.state in (RobotState.RUNNING, RobotState.IDLE):
            self._hold()
        if self.state is RobotState.RUNNING:
            self.state = RobotState.STOPPED
            return True, "stopped: arm holding; resume, skip or abort"
        if self.state is RobotState.IDLE:
            self.state = RobotState.STOPPED
            return True, f"stopped: holding, {len(self.queue)} statement(s) held in the buffer; resume or abort"
        if self.state is RobotState.FAULT:
            return True, "already holding in fault; resume or abort"
        return True, "already stopped"

    def halt(self, reason: str) -> bool:
        """A controlled stop the robot makes by itself: as ``stop``, with ``reason`` kept for
        the console (``halted``) until the operator's recovery. False if it already held."""
        if self.state not in (RobotState.IDLE, RobotState.RUNNING):
            return False
        self.state = RobotState.STOPPED
        self.halted = reason
        self._hold()
        log.warning("robot halted: %s", reason)
        return True

    def resume(self) -> tuple[bool, str]:
        if self.state in (RobotState.STOPPED, RobotState.FAULT):
            self.state = RobotState.RUNNING if self.current is not None else RobotState.IDLE
            self.halted = None
            return True, "resumed"
        return False, f"nothing to resume (robot {self.state.name.lower()})"

    def skip(self, number: int) -> tuple[bool, str]:
        if self.current is None or self.current[0] != number:
            return False, f"statement {number} is not the current one"
        self._finish(StatementState.SKIPPED, "skipped by the operator")
        if self.state is RobotState.STOPPED:
            self.state = RobotState.IDLE
            self.halted = None
        return True, f"statement {number} skipped"

    def abort(self) -> tuple[bool, str]:
        dropped = 0
        if self.current is not None:
            self._finish(StatementState.ABORTED, "aborted by the operator")
            dropped += 1
        while self.queue:
            number, _ = self.queue.popleft()
            self._emit(number, StatementState.ABORTED, "flushed from the buffer by abort")
            dropped += 1
        self.state = RobotState.IDLE
        self.halted = None
        return True, f"aborted {dropped} statement(s)"

    def internal_fault(self, reason: str) -> None:
        """The last-resort boundary caught an error outside any statement's own handling: drop
        the current motion (its statement fails with ``reason``), hold the arm and the queue."""
        self._runner = None
        self.state = RobotState.FAULT
        self.halted = reason
        try:
            self._hold()
        except Exception:  # noqa: BLE001 - a world that cannot even hold is reported, not fatal
            log.exception("cannot hold the arm")
        if self.current is not None:
            number, _ = self.current
            self.current = None
            self._emit(number, StatementState.FAILED, reason)

    # -- the servo loop -----------------------------------------------------------------------
    def tick(self) -> list[ExecutorEvent]:
        """Advance one servo period; return the status changes it produced."""
        self.time += self.dt
        self._commanded = False
        if self.state is RobotState.IDLE and not self.hold_queue and self.current is None and self.queue:
            self._start(*self.queue.popleft())
        if self.state is RobotState.RUNNING and self._runner is not None:
            try:
                next(self._runner)
                if self.physical and self.state is RobotState.RUNNING:
                    self._watch_physics()
            except StopIteration as done:
                self._finish(StatementState.DONE, done.value)
            except (StepFailure, PlanRefused, TeleprogError) as exc:
                self._fail(str(exc))
            except Exception as exc:  # noqa: BLE001 - no statement may end the process
                log.exception("statement %d raised while executing", self.current_number)
                self._fail(f"internal error while executing: {type(exc).__name__}: {_one_line(exc)}")
        if self.physical and not self._commanded:
            self._idle_servo()
        self._sense()
        if not self.sensor_ok and self.state in (RobotState.IDLE, RobotState.RUNNING):
            self.internal_fault(SENSOR_INVALID)  # a robot that cannot feel force neither moves nor waits to
            self.own_fault = (HaltCause.SENSOR_FAULT, SENSOR_INVALID)
        events, self._events = self._events, []
        return events

    def take_own_fault(self) -> tuple[HaltCause, str] | None:
        """Why the robot just went to FAULT by itself, outside a statement's own failure (once), or None."""
        why, self.own_fault = self.own_fault, None
        return why

    def _following_error(self, q_cmd: np.ndarray) -> str | None:
        """Physics: why the arm is not where the joint servo is commanded to ``q_cmd`` (the flange
        further off than ``following_error``), or None. Forward kinematics only past a cheap gate."""
        q = self.world.q
        if float(np.max(np.abs(q - q_cmd))) < _FOLLOW_GATE_RAD:
            return None
        off = float(np.linalg.norm(self.robot.fk(q)[:3, 3] - self.robot.fk(q_cmd)[:3, 3]))
        if off <= self.settings.following_error:
            return None
        return (f"the arm does not follow its servo: the flange is {off * 1e3:.1f} mm from the commanded pose "
                f"(band {self.settings.following_error * 1e3:g} mm; a joint drags or something holds the arm)")

    def drain_events(self) -> list[ExecutorEvent]:
        """Status changes produced outside ``tick`` (by skip or abort), in order."""
        events, self._events = self._events, []
        return events

    def run_until_idle(self, max_seconds: float = 600.0) -> list[ExecutorEvent]:
        """Tick until nothing is running or queued (or the robot waits for the operator)."""
        events: list[ExecutorEvent] = []
        t_end = self.time + max_seconds
        while self.time < t_end:
            events += self.tick()
            if self.current is None and not self.queue:
                break
            if self.state in (RobotState.FAULT, RobotState.STOPPED):
                break
        return events

    # -- statements ---------------------------------------------------------------------------
    def _start(self, number: int, statement: Statement) -> None:
        self.current = (number, statement)
        self.state = RobotState.RUNNING
        self._emit(number, StatementState.RUNNING, None)
        self._runner = self._run(statement)

    def _finish(self, state: StatementState, reason: str | None) -> None:
        assert self.current is not None
        number, _ = self.current
        self.current = None
        self._runner = None
        self._emit(number, state, reason)
        if self.state is RobotState.RUNNING:
            self.state = RobotState.IDLE

    def _fail(self, reason: str) -> None:
        log.warning("statement %s failed: %s", self.current[0] if self.current else "?", reason)
        self._hold()
        self.state = RobotState.FAULT  # before the report, so the report carries it
        self._finish(StatementState.FAILED, reason)

    def _emit(self, number: int, state: StatementState, reason: str | None) -> None:
        self._events.append(ExecutorEvent(number, state, reason[:MAX_TEXT] if reason else reason, self.snapshot()))

    def _run(self, statement: Statement) -> _Runner:
        if isinstance(statement, TaskCall):
            return (yield from self._task(statement))
        self.interpreter.resume_at(self._plan_start())
        segment = self.interpreter.plan_next(statement)
        if isinstance(statement, SetMode):
            self.mode = statement.mode
        if segment.kind is SegmentKind.PARAMETER:
            return f"event {segment.event} reached" if segment.event else None
        outcome = yield from self._play(segment)
        return None if outcome is StopReason.COMPLETED else f"stopped by UNTIL ({outcome.value})"

    def _play(self, segment: Segment, expect_contact: bool = False) -> Generator[None, None, StopReason]:
        """Step a planned motion one servo period per tick; check for surprises on every step."""
        guarded = expect_contact or isinstance(segment.until, (UntilForce, UntilContact)) or self.mode is Mode.FORCE
        limit = self.settings.max_force if guarded else self.settings.contact_limit
        # a motion that starts in contact (after a contact fault the arm rests at the limit) may
        # back away: it fails only where the contact force would grow past the limit or past
        # what it started with, whichever is larger (noise-free: the sensor's noise at the limit
        # must not fail a motion that lifts off)
        start = self.world.contact(self.q, noise=False)
        pressing = max(start.magnitude, limit) if start.touching else None
        self._comply = np.zeros(6)
        self._complying = self.physical and (self.mode is Mode.FORCE or self._in_task)
        stop_force = segment.until.newtons if isinstance(segment.until, UntilForce) else None
        if isinstance(segment.until, UntilContact):
            stop_force = self.settings.touch_force
        stepper = segment.stepper(_WorldSensors(self.world, self.physical), dt=self.dt, t0=self.time)
        while True:
            step = stepper.step()
            if self.physical:
                pressing = self._servo_to(step.q, step.qd, guarded, pressing, stop_force)
            else:
                pressing = self._move_to(step.q, guarded, pressing)
            if step.done:
                return step.reason or StopReason.COMPLETED
            yield

    def _move_to(self, q: np.ndarray, guarded: bool, pressing: float | None = None) -> float | None:
        """Servo to ``q``; on a force over the limit, stop where the limit was crossed and fail.

        ``pressing``: for a motion that started in contact, the largest contact force (N,
        noise-free) the step may reach; the step fails, uncommanded, if the force would grow
        past it. Returns the allowance for the next step (None once out of contact: from then
        on the normal rules apply)."""
        q = np.asarray(q, dtype=float).copy()
        if q.shape != self.q.shape or not np.all(np.isfinite(q)):
            raise StepFailure(f"the planner produced an unusable joint vector {np.array2string(q, precision=4)[:120]}")
        limit = self.settings.max_force if guarded else self.settings.contact_limit
        if pressing is not None:
            felt = self.world.contact(q, noise=False)
            if felt.touching and felt.magnitude > pressing + _FORCE_GROWTH_N:
                raise StepFailure(
                    f"pressing further into {felt.what or 'the contact'} ({felt.magnitude:.1f} N, "
                    f"{pressing:.1f} N at the start); only motions that back away are allowed"
                )
            pressing = max(felt.magnitude, limit) if felt.touching else None
        else:
            contact = self.world.contact(q)
            if contact.touching and contact.magnitude > limit:
                q = self._first_reach(self.q, q, limit)
                self.q = q
                self.world.follow(q)
                felt = self.world.contact(q)
                if guarded:
                    raise StepFailure(f"force {felt.magnitude:.1f} N over the safety limit {limit:g} N ({felt.what})")
                raise StepFailure(f"unplanned contact: {felt.magnitude:.1f} N at {felt.what}")
        # the collision core and the terrain are checked before the step is commanded: the arm
        # holds at the last clear sample, so a later motion away starts out of contact
        if (touch := self._model_contact(q)) is not None:
            raise StepFailure(touch)
        self.q = q
        self.world.follow(q)
        return pressing

    # -- the physics world's servo ---------------------------------------------------------------
    def _servo_to(self, q: np.ndarray, qd: np.ndarray, guarded: bool, pressing: float | None = None,
                  stop_force: float | None = None) -> float | None:
        """Physics: command one servo period towards ``q`` and judge what the sensors then read.

        The collision core still refuses a commanded pose that would put the arm into the cell
        (checked before the command, on the model's shapes at the real objects' poses). What the
        physics does is read after the period, as a force-monitored servo reads it: a force over
        the limit, or any link of the arm touching something, holds the arm where it is and fails
        the statement. ``pressing`` as in ``_move_to``, on the measured force. ``stop_force``: an
        UNTIL FORCE threshold; the force monitor holds the arm within a millisecond of it."""
        q = np.asarray(q, dtype=float).copy()
        if q.shape != self.q.shape or not np.isfinite(q).all():
            raise StepFailure(f"the planner produced an unusable joint vector {np.array2string(q, precision=4)[:120]}")
        qd = np.asarray(qd, dtype=float)
        if not np.isfinite(self.world.wrench).all():
            self._hold()
            raise StepFailure(SENSOR_INVALID)
        if self._complying and guarded:
            q = self._comply_q(q)
        if (touch := self._model_contact(q)) is not None:
            self._hold_clear()
            raise StepFailure(touch)
        limit = self.settings.max_force if guarded else self.settings.contact_limit
        monitor = limit if pressing is None else None
        if stop_force is not None and monitor is not None:
            monitor = min(monitor, stop_force)
        tripped = self.world.servo(q, qd if qd.shape == q.shape and np.isfinite(qd).all() else None, monitor,
                                   guarded=guarded)
        self._setpoint = None if tripped else q
        self._commanded = True
        self.q = self.world.q
        felt = self.world.contact()
        # a lag the wrist cannot explain is a joint that drags: in a motion that expects no
        # contact any lag (a contact would show as force first), in a guarded motion or a task
        # one with no contact force; in contact the force rules govern (a stuck peg holds the arm
        # back by design)
        if (not tripped and (not guarded or felt.magnitude < self.settings.touch_force)
                and (lag := self._following_error(q)) is not None):
            self._hold()
            raise StepFailure(lag)
        if not np.isfinite(felt.force).all():
            self._hold()
            raise StepFailure(SENSOR_INVALID)
        if pressing is not None:
            clean = self.world.contact(noise=False)
            if clean.touching and clean.magnitude > pressing + _PHYSICS_FORCE_GROWTH_N:
                self._hold()
                raise StepFailure(
                    f"pressing further into {clean.what or 'the contact'} ({clean.magnitude:.1f} N, "
                    f"{pressing:.1f} N at the start); only motions that back away are allowed"
                )
            pressing = max(clean.magnitude, limit) if clean.touching else None
        elif felt.magnitude > limit:
            self._hold()
            if guarded:
                raise StepFailure(f"force {felt.magnitude:.1f} N over the safety limit {limit:g} N ({felt.what or 'contact'})")
            raise StepFailure(f"unplanned contact: {felt.magnitude:.1f} N at {felt.what or 'the tool'}")
        return pressing

    def _comply_q(self, q: np.ndarray) -> np.ndarray:
        """Compliance (force mode, and the robot's force-compliant tasks): the tool gives way to
        what the wrist sensor reads, as a remote-centre compliance would. An admittance about the
        tool point: sideways at ``compliance_speed`` per newton across the tool axis, and turning
        at ``compliance_turn`` per newton metre about the axes across it, at most
        ``compliance_range`` and ``compliance_tilt`` from the planned path. A peg that meets a
        chamfer or a wall then slides and turns into line instead of wedging."""
        s = self.settings
        wrench = self.world.wrench_clean
        force = self.world.contact(noise=False).force
        world_T_tcp = self.world.world_T_tcp()
        axis = world_T_tcp[:3, 2]
        lever = world_T_tcp[:3, 3] - self.world.wrist_position()
        torque = wrench[3:] - np.cross(lever, wrench[:3])  # about the tool point
        lateral = force - axis * (axis @ force)
        turning = torque - axis * (axis @ torque)
        self._comply[:3] += self.dt * s.compliance_speed * lateral
        self._comply[3:] += self.dt * s.compliance_turn * turning
        for part, bound in ((slice(0, 3), s.compliance_range), (slice(3, 6), s.compliance_tilt)):
            norm = float(np.linalg.norm(self._comply[part]))
            if norm > bound:
                self._comply[part] *= bound / norm
        if not np.any(self._comply):
            return q
        R_wb = self.cell.world_T_base[:3, :3]
        base_T_flange = self.robot.fk(q)
        base_p_tcp = (base_T_flange @ self.cell.flange_T_tcp)[:3, 3]
        omega = R_wb.T @ self._comply[3:]
        v_tcp = R_wb.T @ self._comply[:3]
        v_flange = v_tcp + np.cross(omega, base_T_flange[:3, 3] - base_p_tcp)
        J = self.robot.jacobian(q)
        return q + np.linalg.lstsq(J, np.concatenate([v_flange, omega]), rcond=None)[0]

    def _plan_start(self) -> np.ndarray:
        """Where a new motion is planned from: the arm (kinematic), or the joint servo's setpoint
        on physics, where the arm a hair behind it is heading (after a contact fault the servo
        holds the last clear pose while the arm settles back onto it)."""
        return self._held_setpoint().copy() if self.physical else self.q

    def _hold_clear(self) -> None:
        """The collision core refused the next sample: the servo holds the last commanded pose,
        which it passed (the physical arm, a little behind it, settles there), so a later motion
        away starts out of contact, as on the kinematic world."""
        self._setpoint = self._held_setpoint()
        self.world.hold_at(self._setpoint)
        self.q = self.world.q
        self._holding_clear = True  # the failure that follows keeps this hold (no brake past it)

    def _held_setpoint(self) -> np.ndarray:
        """The joint target the servo holds now (physics): the last commanded one, or where the
        world's brake stopped the arm."""
        return self._setpoint if self._setpoint is not None else self.world.target

    def _idle_servo(self) -> None:
        """Physics: a tick without a motion still passes for the world; the servo holds its setpoint."""
        try:
            self.world.servo(self._held_setpoint())
        except TeleprogError as exc:  # the simulation diverged while holding
            self.internal_fault(f"physics: {exc}")
            return
        if self.world.held_peg() is not None and (lost := self.world.lost()) is not None:
            if self.current is not None:
                self._fail(lost)
            elif self.state in (RobotState.IDLE, RobotState.RUNNING):  # dropped while waiting for a statement
                self.internal_fault(lost)
                self.own_fault = (HaltCause.OBJECT_LOST, lost)
            return
        if self.state in (RobotState.IDLE, RobotState.RUNNING) and not self.world.asleep and not self._in_task:
            lag = self._following_error(self._held_setpoint())
            if lag is not None:  # holding still and pushed off: a joint drags
                self.internal_fault(lag)
                self.own_fault = (HaltCause.FOLLOWING_ERROR, lag)

    def _watch_physics(self) -> None:
        """After a running statement's tick: what the physics did that nobody planned."""
        lost = self.world.lost()
        if lost is not None:
            raise StepFailure(lost)
        touch = self.world.arm_contact()
        if touch:
            self._hold()
            raise StepFailure(f"unplanned contact: {touch}")

    def _wait(self, seconds: float, until=None, doing: str = "wait") -> Generator[None, None, None]:
        """Let the world go on for ``seconds`` with the arm holding (a task waiting on its gripper,
        ``doing``), or until ``until()`` says there is no point waiting longer. A force past the
        safety limit meanwhile (fingers closing on something held fast) fails ``doing``."""
        for _ in range(max(1, int(round(seconds / self.dt)))):
            self.world.servo(self._held_setpoint())
            self._commanded = True
            felt = self.world.contact()
            if felt.magnitude > self.settings.max_force:  # fingers closing on something held fast
                self._hold()
                raise StepFailure(f"{doing} failed: force {felt.magnitude:.1f} N over the safety limit "
                                  f"{self.settings.max_force:g} N while the fingers moved ({felt.what or 'contact'})")
            if until is not None and until():
                return
            yield

    def _closed_past(self, name: str | None):
        """While the fingers close on ``name``: whether the grasp has failed already, so there is
        no point waiting out the gripper's time: they closed past its width (the grip tolerance
        on: nothing between them), or they stopped without both pads on it (one finger pushing
        something held fast)."""
        half = getattr(self.world, "object_half", {}).get(name) if name else None
        if half is None:
            return None
        from robot_sim.physics.world import HOLD_TOLERANCE

        width = 2.0 * float(np.min(half[:2]))
        last: list[float] = []

        def failed() -> bool:
            opening = self.world.finger_opening()
            if opening < width - HOLD_TOLERANCE:
                return True
            still = len(last) >= 2 and abs(opening - last[-1]) < 2e-5 and abs(last[-1] - last[-2]) < 2e-5
            last.append(opening)
            return still and self.world.held_by_fingers() != name

        return failed

    def _model_contact(self, q: np.ndarray) -> str | None:
        """Why the commanded pose ``q`` would put the arm into the cell (the collision core on the
        real objects' poses, the terrain's own tree), or None when it is clear."""
        if self._scene is not None:
            poses = {name: peg.world_T_peg for name, peg in self._poses_after(q).items()}
            report = self._scene.check(q, object_poses=poses, distances="none", triangles=False, skip=self._skip)
            if report.colliding:
                pair = report.pairs[0]
                return f"unplanned contact: {pair.a} touches {pair.b}"
        if self._terrain is not None and self._terrain.min_distance(q) <= 0.0:
            shape = self._terrain.exact_check(q).shape
            return f"unplanned contact: {shape or 'the arm'} touches the terrain"
        return None

    def _poses_after(self, q: np.ndarray) -> dict[str, PegState]:
        """Where the pegs would be with the arm at ``q`` (a held peg moves with the tool)."""
        out = {}
        for name, peg in self.world.pegs.items():
            if peg.held and peg.tool_T_peg is not None:
                peg = replace(peg, world_T_peg=self.world.world_T_tcp(q) @ peg.tool_T_peg)
            out[name] = peg
        return out

    def _first_reach(self, q_from: np.ndarray, q_to: np.ndarray, limit: float) -> np.ndarray:
        """Where on the servo step from ``q_from`` to ``q_to`` the force first reaches ``limit``
        (bisection: the arm stops there, as a real force-monitored servo would)."""
        lo, hi = 0.0, 1.0
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            if self.world.contact(q_from + mid * (q_to - q_from)).magnitude > limit:
                hi = mid
            else:
                lo = mid
        return q_from + hi * (q_to - q_from)

    def _sense(self) -> None:
        if self.physical:
            self.q = self.world.q
            wrench = np.array(self.world.wrench)  # tared for the gripper: a held peg reads its weight
            self.sensor_ok = bool(np.isfinite(wrench).all())
            self.wrench = wrench if self.sensor_ok else np.zeros(6)  # (the report says why; the wire carries numbers)
            return
        contact = self.world.contact(self.q)
        self.wrench = np.concatenate([contact.force, np.zeros(3)])

    # -- tasks ----------------------------------------------------------------------------------
    def _task(self, call: TaskCall) -> _Runner:
        spec = find_task(call.name)
        self._in_task = True
        try:
            return (yield from self._task_body(call, spec))
        finally:
            self._in_task = False

    def _task_body(self, call: TaskCall, spec) -> _Runner:
        objects = [o.name for o in self.cell.objects]
        features = list(self.cell.features)
        if spec.name == "grasp":
            name = resolve_name(call.args[0], objects) if call.args else None
            if self.physical:
                self.world.close_gripper(name)
                yield from self._wait(self.settings.gripper_time, until=self._closed_past(name), doing="grasp")
                held, detail = self.world.grasp_result()
            else:
                held, detail = self.world.grasp(self.q, name)
            if not held:
                raise StepFailure(f"grasp failed: {detail}")
            return detail
        if spec.name == "release":
            if self.physical:
                if not self.world.gripper_closed and self.world.held_peg() is None:
                    return "gripper opened, holding nothing"  # already open: nothing to wait for
                self.world.open_gripper()
                yield from self._wait(self.settings.gripper_time, doing="release")
                said = self.world.release_result()
            else:
                said = self.world.release(self.q)
            yield from self._retreat(spec)
            return said
        peg = resolve_name(call.args[0], objects) if call.args else None
        hole = resolve_name(call.args[1], features) if len(call.args) > 1 else None
        if peg is None or hole is None:
            raise StepFailure(f"task {call.name}: unknown peg or hole in {call.args}")
        held = self.world.held_peg()
        if held is None or held[0] != peg:
            raise StepFailure(f"task {call.name}: the gripper does not hold {peg}")
        if spec.name == "extract_peg":
            return (yield from self._extract(peg, hole))
        if spec.name == "insert_peg":
            return (yield from self._insert(peg, hole))
        raise StepFailure(f"task {call.name} is known but this robot cannot run it")

    def _tool_line(self, world_p_target: np.ndarray, until: UntilForce | UntilContact | None = None,
                   speed: float | None = None) -> Segment:
        """Plan a straight tool move to a world point at task speed (or ``speed`` m/s), orientation kept."""
        self.interpreter.resume_at(self._plan_start())
        statement = Draw(
            position=tuple(float(v) for v in world_p_target),
            frame=Frame.WORLD,
            speed=Speed(value=self.settings.task_speed, unit=SpeedUnit.FRACTION) if speed is None
            else Speed(value=speed, unit=SpeedUnit.M_PER_S),
            until=until,
        )
        return self.interpreter.plan_next(statement)

    def _world_tcp(self) -> np.ndarray:
        return self.world.world_T_tcp(self.q)

    def _grip(self, peg: str) -> Grip:
        """The held peg as the robot senses it in the fingers (the task effects' grip)."""
        state = self.world.pegs[peg]
        return Grip(peg, state.tool_T_peg, np.array([0.0, 0.0, -float(state.half_size[2])]))

    def _effect_end(self, name: str, hole: str | None = None, peg: str | None = None) -> np.ndarray:
        """Where task ``name``'s declared effect puts the tool from here (world point, m): the
        pose the console's planner predicts, from the grip the robot senses."""
        world_T_hole = None if hole is None else self.cell.features[hole].world_T_feature
        grip = None if peg is None else self._grip(peg)
        depth = None if peg is None else self._model_objects.depths.get(peg)
        end = arm_end(find_task(name).effect, self._world_tcp(), world_T_hole, grip, depth)
        if end is None:
            raise StepFailure(f"task {name}: nothing to aim at (no hole or no grip)")
        return end[:3, 3]

    def _retreat(self, spec) -> Generator[None, None, None]:
        """Back the tool off along its own axis by the task's declared retreat (none: stay)."""
        if spec.effect.arm != "retreat" or spec.effect.distance_m <= 0.0:
            return
        yield from self._play(self._tool_line(self._effect_end(spec.name)), expect_contact=True)

    def _extract(self, peg: str, hole: str) -> _Runner:
        target = self._effect_end("extract_peg", hole)
        segment = self._tool_line(target, until=UntilForce(newtons=self.settings.extract_limit))
        reason = yield from self._play(segment, expect_contact=True)
        if reason is not StopReason.COMPLETED:
            raise StepFailure(f"extract_peg: {peg} is stuck in {hole} (pull over {self.settings.extract_limit:g} N)")
        return f"{peg} extracted from {hole}"

    def _insert(self, peg: str, hole: str) -> _Runner:
        if self.physical:
            return (yield from self._insert_physical(peg, hole))
        s = self.settings
        mouth, axis, depth, seat = self._seat(peg, hole)  # where the model says the hole is
        foot = (mouth - depth * axis) - seat  # the peg's foot from the tool point, world
        # 1. approach: the peg's foot 5 mm above the modelled mouth
        yield from self._play(self._tool_line(seat + (depth + 0.005) * axis))
        # 2. guarded descent to first contact (or straight in if the hole is where the model says)
        reason = yield from self._play(
            self._tool_line(seat - 0.002 * axis, UntilForce(newtons=s.touch_force)),
            expect_contact=True,
        )
        foot_z = lambda: self._world_tcp()[2, 3] + foot[2]  # noqa: E731
        if foot_z() > mouth[2] - 0.002:
            # 3. landed on the plate: force-guided search on a square spiral around the contact
            contact_xy = self._world_tcp()[:2, 3].copy()
            z_touch = self._world_tcp()[2, 3]
            found = False
            for dx, dy in _square_spiral(s.search_step, s.search_radius):
                lift = np.array([*contact_xy + (dx, dy), z_touch + 0.001])
                yield from self._play(self._tool_line(lift))
                probe = np.array([*contact_xy + (dx, dy), z_touch - 0.003])
                yield from self._play(self._tool_line(probe, UntilForce(newtons=s.touch_force)), expect_contact=True)
                if self._world_tcp()[2, 3] < z_touch - 0.002:
                    found = True
                    break
            if not found:
                raise StepFailure(f"insert_peg: no hole found within {s.search_radius * 1e3:g} mm of the first contact")
        # 4. seat the peg: down until the floor pushes back
        here = self._world_tcp()[:3, 3]
        floor_target = np.array([here[0], here[1], mouth[2] - depth - 0.002 - foot[2]])
        reason = yield from self._play(self._tool_line(floor_target, UntilForce(newtons=s.touch_force)), expect_contact=True)
        if reason is StopReason.COMPLETED:
            raise StepFailure(f"insert_peg: {peg} went deeper than {hole}'s floor; the hole is not where expected")
        if self.physical:
            yield from self._seat_physical(peg, hole, mouth, depth, foot)
        return f"{peg} seated in {hole}"

    def _insert_physical(self, peg: str, hole: str) -> _Runner:
        """Insertion on physics, with the tool compliant throughout (``_comply_q``):

        1. approach: the peg's foot ``5 mm`` above the modelled mouth, at task speed;
        2. guarded descent at ``guarded_speed`` until the wrist feels ``touch_force``;
        3. if the foot is not in the hole yet, press down with ``press_force``: on a chamfer or an
           edge the push turns sideways and the compliance slides the peg in;
        4. still out: a square spiral round the first contact, each probe lifting ``1 mm``, moving
           over and pressing again, until the foot drops ``2 mm`` below where it touched;
        5. seat the peg (``_seat_physical``): down to the floor, or jammed."""
        s = self.settings
        mouth, axis, depth, seat = self._seat(peg, hole)
        foot = (mouth - depth * axis) - seat  # the peg's foot from the tool point, world
        slow = s.guarded_speed
        yield from self._play(self._tool_line(seat + (depth + 0.005) * axis))
        yield from self._play(self._tool_line(seat - 0.002 * axis,
                                              UntilForce(newtons=s.touch_force), speed=slow), expect_contact=True)
        z_touch = self._world_tcp()[2, 3]
        inside = lambda: self._world_tcp()[2, 3] + foot[2] < mouth[2] - 0.002  # noqa: E731
        if not inside():
            yield from self._press(mouth[2] - depth - 0.002 - foot[2])
        if not inside():
            found = yield from self._spiral_search(z_touch)
            if not found:
                self._hold()
                raise StepFailure(f"insert_peg: no hole found within {s.search_radius * 1e3:g} mm of the first contact")
        here = self._world_tcp()[:3, 3]
        yield from self._play(self._tool_line(np.array([here[0], here[1], mouth[2] - depth - 0.002 - foot[2]]),
                                              UntilForce(newtons=s.touch_force), speed=slow), expect_contact=True)
        yield from self._seat_physical(peg, hole, mouth, depth, foot)
        yield from self._centre_over_tool()
        # the robot's perception of the peg, not the tool's depth: a peg that slid up in the
        # fingers leaves the tool at the seat and the peg short of it
        seen = self.world.pegs[peg]
        T = seen.world_T_peg
        foot_z = T[2, 3] - T[2, 2] * float(seen.half_size[2])
        short = (foot_z - (mouth[2] - depth)) if seen.in_hole == hole else None
        if short is None or short > self.settings.seat_tolerance:
            self._hold()
            where = f"{short * 1e3:.1f} mm short of {hole}'s floor" if short is not None else (
                f"in {seen.in_hole}" if seen.in_hole else "in no hole")
            raise StepFailure(f"insert_peg: the tool is at the seat but {peg} is {where} (it slid in the fingers?)")
        return f"{peg} seated in {hole}"

    def _seat(self, peg: str, hole: str) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        """The modelled hole's mouth and axis, the seat depth and the tool point at the seat
        ``insert_peg``'s declared effect names (world, m), from the grip the robot senses."""
        world_T_hole = self.cell.features[hole].world_T_feature
        depth = float(self._model_objects.depths.get(peg, self.world.settings.hole_depth))
        return world_T_hole[:3, 3].copy(), world_T_hole[:3, 2].copy(), depth, self._effect_end("insert_peg", hole, peg)

    def _centre_over_tool(self) -> Generator[None, None, None]:
        """Physics: the seated peg holds the tool over the real hole while the arm stands where
        the search left it, the compliant wrist bent between them. Bring the arm over the tool
        (the wrist straight), so the arm ends at the seat and the tool does not spring aside when
        the fingers open."""
        here = self.world.world_T_tcp()[:3, 3]
        if np.linalg.norm(here - self._world_tcp()[:3, 3]) < 1e-4:
            return
        yield from self._play(self._tool_line(here, speed=self.settings.guarded_speed), expect_contact=True)

    def _spiral_search(self, z_touch: float) -> Generator[None, None, bool]:
        """Physics: slide the peg over the surface on an Archimedean spiral round the first
        contact (pitch ``search_pitch``, at ``search_speed``), pressing down with ``press_force``
        (a force loop on the wrist's vertical reading sets the tool's height), until the peg drops
        ``2 mm`` below where it touched (found) or the spiral passes ``search_radius``."""
        s = self.settings
        world_T_tcp = self._world_tcp()
        centre = world_T_tcp[:3, 3].copy()
        R_wb = self.cell.world_T_base[:3, :3]
        b = s.search_pitch / (2.0 * np.pi)
        theta, z = 0.0, centre[2]
        q = self._held_setpoint().copy()
        mode, self.mode = self.mode, Mode.FORCE
        self._comply = np.zeros(6)
        self._complying = False  # the spiral is the sideways motion; the wrist's springs comply
        try:
            while b * theta <= s.search_radius:
                felt = self.world.contact(noise=False).force[2]  # the surface pushes the tool up: > 0
                if felt > 0.3 * s.press_force:  # on the surface: slide on; falling in: hold still
                    theta += s.search_speed * self.dt / max(np.hypot(b * theta, b), 1e-9)
                r = b * theta
                z += self.dt * s.force_gain * (felt - s.press_force)
                target = np.array([centre[0] + r * np.cos(theta), centre[1] + r * np.sin(theta), z])
                here = (self.cell.world_T_base @ self.robot.fk(q) @ self.cell.flange_T_tcp)[:3, 3]
                J = self.robot.jacobian(q)
                dq = np.linalg.lstsq(J, np.concatenate([R_wb.T @ (target - here), np.zeros(3)]), rcond=None)[0]
                q = q + dq
                self._servo_to(q, dq / self.dt, guarded=True)
                yield
                if self._world_tcp()[2, 3] < z_touch - 0.002:
                    return True
        finally:
            self.mode = mode
        return False

    def _press(self, z_target: float) -> Generator[None, None, None]:
        """Push the tool straight down towards ``z_target`` at ``guarded_speed`` until the wrist
        reads ``press_force`` (compliance on: a chamfer under the peg turns the push sideways)."""
        here = self._world_tcp()[:3, 3]
        yield from self._play(self._tool_line(np.array([here[0], here[1], z_target]),
                                              UntilForce(newtons=self.settings.press_force),
                                              speed=self.settings.guarded_speed), expect_contact=True)
        # let the compliance finish sliding under the held push
        for _ in range(int(round(self.settings.press_settle / self.dt))):
            self._servo_to(self._held_setpoint(), np.zeros_like(self.q), guarded=True)
            yield

    def _seat_physical(self, peg: str, hole: str, mouth: np.ndarray, depth: float, foot: np.ndarray) -> Generator[None, None, None]:
        """Physics: the descent stopped on a force; the peg is seated only if its foot is near
        the hole's floor. Otherwise push on with ``seat_force`` in force mode's compliance for
        ``jam_time``: a peg that makes no progress then is jammed (wedged or stuck on a wall)."""
        s = self.settings
        foot_depth = lambda: mouth[2] - (self._world_tcp()[2, 3] + foot[2])  # noqa: E731
        if foot_depth() >= depth - s.seat_tolerance:
            return
        here = self._world_tcp()[:3, 3]
        push = self._tool_line(np.array([here[0], here[1], mouth[2] - depth - 0.002 - foot[2]]),
                               UntilForce(newtons=s.seat_force))
        best, since = foot_depth(), self.time
        stepper = push.stepper(_WorldSensors(self.world, physical=True), dt=self.dt, t0=self.time)
        mode, self.mode = self.mode, Mode.FORCE
        try:
            self._comply = np.zeros(6)
            self._complying = True
            while self.time - since < s.jam_time:
                step = stepper.step()
                if not step.done:
                    self._servo_to(step.q, step.qd, guarded=True)
                else:
                    self._servo_to(self._held_setpoint(), np.zeros_like(self.q), guarded=True)
                yield
                now = foot_depth()
                if now >= depth - s.seat_tolerance:
                    return
                if now > best + 1e-4:
                    best, since = now, self.time
        finally:
            self.mode = mode
        self._hold()
        raise StepFailure(
            f"insert_peg: {peg} jammed {max(foot_depth(), 0.0) * 1e3:.1f} mm into {hole} of {depth * 1e3:.0f} mm "
            f"(force {self.world.contact().magnitude:.1f} N, no progress in {s.jam_time:g} s)")

    # -- reports --------------------------------------------------------------------------------
    def snapshot(self) -> RobotSnapshot:
        if self.physical:  # the tool as it is: the compliant wrist's deflection included
            base_T_tcp = np.linalg.inv(self.cell.world_T_base) @ self.world.world_T_tcp()
        else:
            base_T_tcp = self.robot.fk(self.q) @ self.cell.flange_T_tcp
        return RobotSnapshot(
            state=self.state,
            mode=ControlMode.FORCE if self.mode is Mode.FORCE else ControlMode.POSITION,
            q=tuple(float(v) for v in self.q),
            base_p_tool=tuple(float(v) for v in base_T_tcp[:3, 3]),
            tool_rpy=tuple(float(v) for v in matrix_to_rpy(base_T_tcp[:3, :3])),
            gripper=0.0 if self.world.gripper_closed else 0.03,
            wrench=tuple(float(v) for v in self.wrench),
            held=held[0] if (held := self.world.held_peg()) is not None else None,
            objects=self.world.perceived_objects(),
        )

    @property
    def current_number(self) -> int:
        return self.current[0] if self.current is not None else 0


class _WorldSensors:
    """The world's force sensor as the planner's ``SensorModel``. On physics it reads the present
    (the pose asked about is where the arm is going, not where it is): a guarded motion stops
    where the arm was when the force crossed its threshold."""

    def __init__(self, world, physical: bool = False) -> None:
        self.world = world
        self.physical = physical

    def force(self, t: float, q: np.ndarray) -> float:
        return self.world.contact(None if self.physical else q).magnitude

    def contact(self, t: float, q: np.ndarray) -> bool:
        return self.world.contact(None if self.physical else q).touching


def _square_spiral(step: float, radius: float) -> Iterator[tuple[float, float]]:
    """Offsets on a square spiral out from the origin: (0,0), (s,0), (s,s), (0,s), (-s,s), ..."""
    x = y = 0.0
    yield x, y
    leg, direction = 1, 0
    moves = ((1, 0), (0, 1), (-1, 0), (0, -1))
    while max(abs(x), abs(y)) <= radius:
        for _ in range(2):
            dx, dy = moves[direction % 4]
            for _ in range(leg):
                x, y = x + dx * step, y + dy * step
                if max(abs(x), abs(y)) > radius:
                    return
                yield x, y
            direction += 1
        leg += 1
