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
same interpreter: ``insert_peg`` approaches the hole, descends until contact, searches around
the contact point with the force sensor when the peg lands on the plate, then seats the peg;
``extract_peg`` pulls the peg out along the hole's axis and fails if it sticks.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Generator, Iterator
from dataclasses import dataclass, replace

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
from shared.language.tasks import EXTRACT_LIFT_M, find_task, resolve_name
from shared.motion import Interpreter, PlanRefused, Segment, SegmentKind, StopReason
from shared.spatial import matrix_to_rpy
from shared.terrain.cell import TERRAIN_OBJECT, has_terrain, load_cell_terrain
from shared.wire.messages import MAX_TEXT, ControlMode, RobotSnapshot, RobotState, StatementState
from robot_sim.settings import ExecutorSettings
from robot_sim.world import PegState, SimWorld

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

_FORCE_GROWTH_N = 1e-6
"""Growth of a start-in-contact force that counts as pressing further (N; the force is noise-free)."""


def _one_line(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return text[:300]


class Executor:
    """One arm, one buffer of numbered statements, stepped one servo period at a time."""

    def __init__(self, cell: Cell, world: SimWorld, settings: ExecutorSettings | None = None, q0: np.ndarray | None = None,
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
        self.state = RobotState.IDLE
        self.mode = Mode.POSITION
        zones = None
        if self.settings.interference_zones and self.robot.dof >= 3:
            from shared.collision.interference import robot_zones

            zones = robot_zones(self.robot)
        self.interpreter = Interpreter.for_cell(cell, self.q, zones=zones)
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

    def stop(self) -> tuple[bool, str]:
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
        if self.current is not None:
            number, _ = self.current
            self.current = None
            self._emit(number, StatementState.FAILED, reason)

    # -- the servo loop -----------------------------------------------------------------------
    def tick(self) -> list[ExecutorEvent]:
        """Advance one servo period; return the status changes it produced."""
        self.time += self.dt
        if self.state is RobotState.IDLE and not self.hold_queue and self.current is None and self.queue:
            self._start(*self.queue.popleft())
        if self.state is RobotState.RUNNING and self._runner is not None:
            try:
                next(self._runner)
            except StopIteration as done:
                self._finish(StatementState.DONE, done.value)
            except (StepFailure, PlanRefused, TeleprogError) as exc:
                self._fail(str(exc))
            except Exception as exc:  # noqa: BLE001 - no statement may end the process
                log.exception("statement %d raised while executing", self.current_number)
                self._fail(f"internal error while executing: {type(exc).__name__}: {_one_line(exc)}")
        self._sense()
        events, self._events = self._events, []
        return events

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
        self.state = RobotState.FAULT  # before the report, so the report carries it
        self._finish(StatementState.FAILED, reason)

    def _emit(self, number: int, state: StatementState, reason: str | None) -> None:
        self._events.append(ExecutorEvent(number, state, reason[:MAX_TEXT] if reason else reason, self.snapshot()))

    def _run(self, statement: Statement) -> _Runner:
        if isinstance(statement, TaskCall):
            return (yield from self._task(statement))
        self.interpreter.resume_at(self.q)
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
        stepper = segment.stepper(_WorldSensors(self.world), dt=self.dt, t0=self.time)
        while True:
            step = stepper.step()
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
        if self._scene is not None:
            poses = {name: peg.world_T_peg for name, peg in self._poses_after(q).items()}
            report = self._scene.check(q, object_poses=poses, distances="none", triangles=False, skip=self._skip)
            if report.colliding:
                pair = report.pairs[0]
                raise StepFailure(f"unplanned contact: {pair.a} touches {pair.b}")
        if self._terrain is not None and self._terrain.min_distance(q) <= 0.0:
            shape = self._terrain.exact_check(q).shape
            raise StepFailure(f"unplanned contact: {shape or 'the arm'} touches the terrain")
        self.q = q
        self.world.follow(q)
        return pressing

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
        contact = self.world.contact(self.q)
        self.wrench = np.concatenate([contact.force, np.zeros(3)])

    # -- tasks ----------------------------------------------------------------------------------
    def _task(self, call: TaskCall) -> _Runner:
        spec = find_task(call.name)
        objects = [o.name for o in self.cell.objects]
        features = list(self.cell.features)
        if spec.name == "grasp":
            name = resolve_name(call.args[0], objects) if call.args else None
            held, detail = self.world.grasp(self.q, name)
            if not held:
                raise StepFailure(f"grasp failed: {detail}")
            return detail
        if spec.name == "release":
            return self.world.release(self.q)
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

    def _tool_line(self, world_p_target: np.ndarray, until: UntilForce | UntilContact | None = None) -> Segment:
        """Plan a straight tool move to a world point at task speed, orientation kept."""
        self.interpreter.resume_at(self.q)
        statement = Draw(
            position=tuple(float(v) for v in world_p_target),
            frame=Frame.WORLD,
            speed=Speed(value=self.settings.task_speed, unit=SpeedUnit.FRACTION),
            until=until,
        )
        return self.interpreter.plan_next(statement)

    def _world_tcp(self) -> np.ndarray:
        return self.world.world_T_tcp(self.q)

    def _foot_offset(self, peg: str) -> np.ndarray:
        """Vector from the tool centre point to the peg's foot, in the world frame."""
        state = self.world.pegs[peg]
        world_T_peg = self._world_tcp() @ state.tool_T_peg
        foot = world_T_peg[:3, 3] - world_T_peg[:3, 2] * state.half_size[2]
        return foot - self._world_tcp()[:3, 3]

    def _extract(self, peg: str, hole: str) -> _Runner:
        axis = self.cell.features[hole].world_T_feature[:3, 2]
        target = self._world_tcp()[:3, 3] + EXTRACT_LIFT_M * axis
        segment = self._tool_line(target, until=UntilForce(newtons=self.settings.extract_limit))
        reason = yield from self._play(segment, expect_contact=True)
        if reason is not StopReason.COMPLETED:
            raise StepFailure(f"extract_peg: {peg} is stuck in {hole} (pull over {self.settings.extract_limit:g} N)")
        return f"{peg} extracted from {hole}"

    def _insert(self, peg: str, hole: str) -> _Runner:
        s = self.settings
        mouth = self.cell.features[hole].world_T_feature[:3, 3]  # where the model says the hole is
        foot = self._foot_offset(peg)
        depth = self.world.settings.hole_depth
        # 1. approach: the peg's foot 5 mm above the modelled mouth
        yield from self._play(self._tool_line(mouth + np.array([0.0, 0.0, 0.005]) - foot))
        # 2. guarded descent to first contact (or straight in if the hole is where the model says)
        reason = yield from self._play(
            self._tool_line(mouth - np.array([0.0, 0.0, depth + 0.002]) - foot, UntilForce(newtons=s.touch_force)),
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
        return f"{peg} seated in {hole}"

    # -- reports --------------------------------------------------------------------------------
    def snapshot(self) -> RobotSnapshot:
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
    """The world's force sensor as the planner's ``SensorModel``."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world

    def force(self, t: float, q: np.ndarray) -> float:
        return self.world.contact(q).magnitude

    def contact(self, t: float, q: np.ndarray) -> bool:
        return self.world.contact(q).touching


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
