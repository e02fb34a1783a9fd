"""A trial's session in virtual time (``--clock virtual``): console, link and telerobot in one
process, on one clock stepped by the robot's servo period.

The parts are the sans-I/O cores the real processes run: the console's ``CommandSender`` (numbering,
keeping and re-sending units) and its planner (``shared.motion.Interpreter``: the virtual robot),
``LinkCore`` (the delay each way), and ``RobotCore`` (receiver and executor over the seeded
world, ``robot_sim.worlds``). What the real processes add (sockets, asyncio, the HTTP API, the page) is left out;
what they do with a statement is not. The console sends a heartbeat every
``HEARTBEAT_INTERVAL_S`` as the real one does, so the robot's silence watch runs as in a session.

The console's virtual arm is the interpreter: generating a statement plans it from where the
previous one ended, so its duration is the virtual robot's time, and a statement the planner
refuses is refused here as the console would refuse it. The objects of the virtual world follow the
generated grasps and releases (``shared.cells.object_world``), so the control zone of the virtual
arm (``shared.collision.zones``) is the one the console would show.

Heavy parts that do not depend on the run (the cell, its collision model) are built once per
process and shared by every run in it (:func:`cell_parts`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from robot_sim.core import RobotCore
from robot_sim.executor import Executor
from robot_sim.settings import WorldSettings
from robot_sim.worlds import make_world
from server.trials.drivers import Clock, SentRecord, settled
from server.trials.session import TrialError
from shared.cells.cell import Cell
from shared.cells.loader import load_cell
from shared.cells.object_world import ObjectWorld
from shared.collision import SceneModel
from shared.collision.zones import zone
from shared.language.parser import parse_statement
from shared.language.statements import Statement, TaskCall
from shared.link.core import Direction, LinkCore, LinkFault, LinkParams
from shared.motion import Interpreter, PlanRefused
from shared.wire.liveness import HEARTBEAT_INTERVAL_S
from shared.wire.messages import Accepted, Heartbeat, Rejected, StatementState, StatusReport, decode_message, encode_message
from shared.wire.session import CommandSender

CLIENT_ID = "teleprog trial (virtual)"


class TickObserver(Protocol):
    """Something that watches (or changes) the session after every servo period: a fault
    campaign's injector and judge (``server.trials.faults``)."""

    def on_tick(self, driver: VirtualDriver) -> None: ...

    def next_due(self) -> float | None:
        """The next time it must see a tick at, or None (idle periods are skipped up to it)."""


@dataclass(frozen=True)
class CellParts:
    cell: Cell
    scene: SceneModel


@functools.lru_cache(maxsize=8)
def cell_parts(cell_path: str) -> CellParts:
    """The cell and its collision model, built once per process for every run on that cell."""
    cell = load_cell(Path(cell_path))
    return CellParts(cell, SceneModel.from_cell(cell))


def warm(cell_path: str | Path) -> None:
    """Build what every run in this process shares (the cell, its collision model, the compiled
    kernels a first run would compile) before runs start, or before worker processes fork."""
    driver = VirtualDriver(cell_path, WorldSettings(), 0.0)
    driver.wait_welcome()
    driver.generate(["SPEED 50 %"])
    driver.finals(driver.send(), 5.0)


class VirtualDriver:
    """One run's session in virtual time; the :class:`server.trials.drivers.Driver` interface."""

    clock: Clock = "virtual"

    def __init__(self, cell_path: str | Path, world: WorldSettings, delay_s: float, link: LinkParams | None = None) -> None:
        self.parts = cell_parts(str(cell_path))
        self.cell = self.parts.cell
        self.world_settings = world
        self.delay_s = delay_s
        self.link_params = link.model_copy(update={"delay_s": delay_s}) if link is not None else LinkParams(delay_s=delay_s)
        self.sent: list[SentRecord] = []  # every record sent, in order
        self.link_losses: list[float] = []  # when a lost message cut the connection (a lossy link)
        self.last_up_delivery: float | None = None  # when the robot last received anything (ground truth)
        self.robot_said: list[tuple[float, str | None]] = []  # failures and halts as the robot sent them (its clock)
        self.t = 0.0
        self.observers: list[TickObserver] = []  # a fault campaign's injector and judge
        self.console_silent = (0.0, 0.0)  # a frozen console sends no heartbeat in this window
        self._new_robot()

    # -- the session ----------------------------------------------------------------------------
    def _new_robot(self) -> None:
        cell = self.cell
        executor = Executor(cell, make_world(cell, self.world_settings), scene=self.parts.scene)
        self.robot = RobotCore(executor, session_id=f"virtual-{self.world_settings.seed}")
        self.dt = executor.dt
        executor.time = self.t  # one clock for the robot and the console
        self.sender = CommandSender(CLIENT_ID)
        self.link = LinkCore(self.link_params)
        self._reconnect_at: float | None = None
        self.interp = Interpreter.for_cell(cell, cell.q_home)
        self.objects = ObjectWorld(cell)
        self._unsent: list[tuple[Statement, SentRecord]] = []
        self._by_comm: dict[int, list[SentRecord]] = {}
        self._by_number: dict[int, SentRecord] = {}
        self._early: dict[int, list[StatusReport]] = {}
        self._started: dict[int, tuple[float, float | None]] = {}
        self._next_id = 1
        self._heartbeat_seq = 0
        self._next_heartbeat = self.t
        self.robot.connect()
        self.link.send(self.t, Direction.UP, encode_message(self.sender.hello()))
        self.halts: list[str] = []

    def restart_at_start(self, back_to_start: str) -> None:  # noqa: ARG002 - a fresh robot is free here
        """A fresh telerobot at home on the same seeded world, the clock going on (the real driver
        drives the arm back instead; both modes then start from the same pose)."""
        self._new_robot()
        self.wait_welcome()

    def wait_welcome(self) -> None:
        """Run until the robot's welcome is back (one round trip of the link), as a session's link
        comes up before the operator starts."""
        self._run_until(lambda: self.sender.session_id is not None, 2 * self.delay_s + 5.0, "the robot's welcome")

    def _step(self) -> None:
        self.t += self.dt
        if self.t + 1e-12 >= self._next_heartbeat:
            if not self.console_silent[0] <= self.t < self.console_silent[1]:
                self.link.send(self.t, Direction.UP, encode_message(Heartbeat(seq=self._heartbeat_seq)))
                self._heartbeat_seq += 1
            self._next_heartbeat += HEARTBEAT_INTERVAL_S
        if self._reconnect_at is not None and self.t >= self._reconnect_at:
            self._reconnect_at = None  # the console connects again: hello, welcome, and re-sending
            self.robot.connect()
            self.link.send(self.t, Direction.UP, encode_message(self.sender.hello()))
        for item in self.link.poll(self.t):
            if isinstance(item, LinkFault):  # a lost message broke the connection (a lossy link)
                self.link_losses.append(item.at)
                self.robot.disconnect()
                self._reconnect_at = item.up_at
                continue
            if item.direction is Direction.UP:
                self.last_up_delivery = self.t
                data = item.payload
                replies = self.robot.on_unit(data) if isinstance(data, bytes) else self.robot.on_text(data)
                for m in replies:
                    self.link.send(self.t, Direction.DOWN, encode_message(m))
            else:
                self._on_message(decode_message(item.payload))
        for m in self.robot.tick():
            if isinstance(m, StatusReport) and m.state is StatementState.FAILED or m.type == "halted":
                self.robot_said.append((self.t, m.reason if isinstance(m, StatusReport) else f"{m.cause.value}: {m.detail}"))
            self.link.send(self.t, Direction.DOWN, encode_message(m))
        for observer in self.observers:
            observer.on_tick(self)

    def _on_message(self, msg) -> None:
        if msg.type == "welcome":
            for again in self.sender.on_welcome(msg):
                self.link.send(self.t, Direction.UP, again if isinstance(again, bytes) else encode_message(again))
            return
        self.sender.on_message(msg)
        if isinstance(msg, Accepted):
            # a communication re-sent after a reconnection is acknowledged again: its records
            # were numbered on the first acknowledgement
            records = self._by_comm.pop(msg.comm_id, None)
            if records is None:
                return
            for record, number in zip(records, msg.numbers, strict=True):
                record.status = "received"
                self._by_number[number] = record
                for report in self._early.pop(number, []):
                    self._report(record, report)
        elif isinstance(msg, Rejected) and msg.final and msg.comm_id is not None:
            for record in self._by_comm.pop(msg.comm_id, []):
                record.status, record.reason, record.finished_at = "rejected", msg.detail, self.t
        elif isinstance(msg, StatusReport):
            record = self._by_number.get(msg.number)
            if record is None:
                self._early.setdefault(msg.number, []).append(msg)
            else:
                self._report(record, msg)
        elif msg.type == "halted":
            self.halts.append(f"{msg.cause.value}: {msg.detail}")

    def _report(self, record: SentRecord, report: StatusReport) -> None:
        if record.final:
            return
        if report.state is StatementState.RUNNING:
            self._started.setdefault(record.id, (self.t, report.robot_time))
        elif report.state.value in ("done", "failed", "skipped", "aborted"):
            started, robot_started = self._started.get(record.id, (self.t, report.robot_time))
            record.finished_at, record.run_s = self.t, self.t - started
            if report.robot_time is not None and robot_started is not None:
                record.robot_run_s = report.robot_time - robot_started
        record.status, record.reason = report.state.value, report.reason or record.reason

    def _advance(self, limit: float) -> None:
        """One servo period; while the robot is idle, first skip the periods in which nothing can
        happen: up to the servo period before the next delivery, console heartbeat or ``limit``
        (an idle executor's tick only moves its clock; ``RobotCore.skip_idle``)."""
        due = [x for x in (self.link.next_due(), self._next_heartbeat, limit, self._reconnect_at, *(o.next_due() for o in self.observers))
               if x is not None]
        periods = int((min(due) - self.t) / self.dt + 1e-9) - 1
        if periods > 0 and self.robot.skip_idle(self.t + periods * self.dt):
            self.t = self.robot.executor.time
        self._step()

    def _run_until(self, done, timeout: float, what: str) -> None:
        end = self.t + timeout
        while not done():
            if self.t > end:
                raise TrialError(f"{what} not within {timeout:g} s (virtual time)")
            self._advance(end)

    # -- the Driver interface ----------------------------------------------------------------
    def now(self) -> float:
        return self.t

    def wait_until(self, t: float) -> None:
        while self.t + 1e-9 < t:
            self._advance(t)

    def generate(self, texts: list[str]) -> list[float]:
        """The operator makes ``texts`` on the virtual arm: each is planned where the previous one
        ended (its duration: the virtual robot's time); they wait in the program until ``send``."""
        planned = []
        for text in texts:
            statement = parse_statement(text)
            try:
                segment = self.interp.plan_next(statement)
            except PlanRefused as exc:
                raise TrialError(f"the console's planner refuses {text!r}: {exc}") from exc
            if isinstance(statement, TaskCall):
                self.objects.apply_task(statement.name, statement.args, self._world_T_tcp())
            record = SentRecord(id=self._next_id, text=text, planned_s=float(segment.duration))
            self._next_id += 1
            self._unsent.append((statement, record))
            planned.append(record.planned_s)
        return planned

    def send(self, *, previewed: bool = False) -> list[SentRecord]:  # noqa: ARG002 - planned at generation
        """Submit what was generated and not sent, as one communication."""
        if not self._unsent:
            return []
        statements = [s for s, _ in self._unsent]
        records = [r for _, r in self._unsent]
        self._unsent = []
        comm_id, units = self.sender.submit(statements)
        self._by_comm[comm_id] = records
        for r in records:
            r.submitted_at = self.t
        self.sent += records
        for unit in units:
            self.link.send(self.t, Direction.UP, unit)
        return records

    def finals(self, records: list[SentRecord], timeout: float) -> list[SentRecord]:
        ids = sorted(r.id for r in records)
        self._run_until(lambda: settled(records), timeout, f"final reports of statements {ids}")
        return records

    def zone(self) -> str:
        """The control zone of the virtual arm where the generated statements end."""
        q = self.interp.state.q
        held = [self.objects.held] if self.objects.held else []
        state = zone(self.parts.scene, self.cell, q, held=held, object_poses=self.objects.poses(self._world_T_tcp()))
        return state.zone

    def one_way_delay_s(self) -> float:
        return self.delay_s

    def _world_T_tcp(self) -> np.ndarray:
        cell = self.cell
        return cell.world_T_base @ cell.robot.fk(self.interp.state.q) @ cell.flange_T_tcp

    # -- what the robot did (for tests and reports) ---------------------------------------------
    @property
    def world(self):
        """The telerobot's world (``robot_sim.worlds``: physics or kinematic)."""
        return self.robot.executor.world
