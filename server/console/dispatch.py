"""Dispatch (thesis §4.2.1-4.2.2): statements leave the program for the robot, get the robot's
numbers, and move through their statuses as its reports arrive.

``submit`` applies the regime: in quasi-operation the range must have been previewed to its end
without warnings; in operation one statement goes at a time, each action with an UNTIL, in force
mode. The statements leave the program at once and join the sent list as ``sending``; the send
itself runs on the robot client's loop and is never waited for. The program then starts where
the sent statements are predicted to end (and a grasp or release among them changes what the
virtual gripper holds). Reports that arrive before their numbers are kept until the numbers come.
A robot that began a new session leaves every unanswered statement ``unknown``.
"""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

from server.console.context import ConsoleContext
from server.console.enums import FINAL_SENT, Regime, SentStatus
from server.console.errors import ConflictError, NotConnectedError, RefusedByRule
from server.console.events import (
    LinkChanged,
    Notice,
    ProgramChanged,
    SentChanged,
)
from server.console.robot_seam import RobotLink
from server.console.statement_checks import checked_statement, statement_text
from server.console.views import Caller, SentListView, SentView
from server.robot_client import RobotRestarted
from shared.errors import InputError, TeleprogError
from shared.language.statements import Mode, SetMode, Statement, TaskCall, is_action
from shared.motion import Plan
from shared.motion.plan_check import plan_or_refuse
from shared.program.editor import Refusal
from shared.robots.jog import world_T_tcp
from shared.wire.messages import StatusReport
from shared.wire.session import SessionRestart

if TYPE_CHECKING:
    from server.console.arm import VirtualArm
    from server.console.control import ControlLock
    from server.console.link_status import LinkStatus
    from server.console.modes import Modes
    from server.console.program_desk import ProgramDesk
    from server.console.remote import RemoteMirror

log = logging.getLogger(__name__)

NO_ROBOT = "no robot is configured for this console (started with --no-robot)"


@dataclass
class Sent:
    """One statement in the sent list."""

    id: int
    statement: Statement
    status: SentStatus
    submitted_at: float
    comm: int  # console-local communication id
    number: int | None = None
    reason: str | None = None
    answered_at: float | None = None
    started_at: float | None = None
    finished_at: float | None = None

    @property
    def final(self) -> bool:
        return self.status in FINAL_SENT

    def view(self) -> SentView:
        run = self.finished_at - self.started_at if self.finished_at is not None and self.started_at is not None else None
        return SentView(
            id=self.id, number=self.number, text=statement_text(self.statement), statement=self.statement,
            status=self.status, reason=self.reason, submitted_at=self.submitted_at, answered_at=self.answered_at,
            started_at=self.started_at, finished_at=self.finished_at, run_s=run,
        )


class Dispatch:
    """The robot seam, the sent list and the statuses."""

    def __init__(self, ctx: ConsoleContext, control: ControlLock, modes: Modes, desk: ProgramDesk, arm: VirtualArm) -> None:
        self._ctx = ctx
        self._control, self._modes, self._desk, self._arm = control, modes, desk, arm
        self.remote: RemoteMirror | None = None  # set by the session
        self.link: LinkStatus | None = None  # set by the session
        self.robot: RobotLink | None = None
        self.loop: asyncio.AbstractEventLoop | None = None
        self.url: str | None = None
        self.sent: list[Sent] = []
        self._by_number: dict[int, Sent] = {}
        self._early: dict[int, list[StatusReport]] = {}
        self._comms = 0
        self.robot_mode = Mode.POSITION
        self.round_trips: list[float] = []

    # -- the seam ------------------------------------------------------------------------------
    def attach(self, robot: RobotLink, loop: asyncio.AbstractEventLoop) -> None:
        """Use ``robot`` on ``loop`` for submissions, recovery and telemetry (once, at start)."""
        with self._ctx.lock:
            self.robot, self.loop, self.url = robot, loop, robot.url
        robot.on_report(self.on_report)
        robot.on_telemetry(self.remote.on_telemetry)
        robot.on_restart(self.on_robot_restart)

    @property
    def connected(self) -> bool:
        """Whether a robot is configured (it may be unreachable right now)."""
        return self.robot is not None

    def need_robot(self) -> tuple[RobotLink, asyncio.AbstractEventLoop]:
        if self.robot is None or self.loop is None:
            raise NotConnectedError(NO_ROBOT)
        return self.robot, self.loop

    def note_round_trip(self, seconds: float) -> None:
        """Record a measured round trip (connection handshake, submit answer, recovery ack)."""
        with self._ctx.lock:
            self.round_trips.append(float(seconds))
            del self.round_trips[:-20]

    # -- views ---------------------------------------------------------------------------------
    def view(self) -> SentListView:
        with self._ctx.lock:
            return SentListView(items=[s.view() for s in self.sent], pending=sum(not s.final for s in self.sent))

    def pending(self) -> list[Sent]:
        with self._ctx.lock:
            return [s for s in self.sent if not s.final]

    # -- submitting ------------------------------------------------------------------------------
    def submit(self, start: int, stop: int, *, client: Caller | str | None = None) -> SentListView:
        """Send ``statements[start:stop]`` (``start`` must be 0) to the robot, under the regime."""
        with self._ctx.lock:
            self._control.check(client)
            robot, loop = self.need_robot()
            self._desk.check_not_previewing("submit statements")
            editor = self._desk.editor
            check = editor.state.check_submit(start, stop)
            if check is not None:
                raise RefusedByRule(check)
            statements = list(editor.state.statements[start:stop])
            outgoing = self._regime_prefix(statements, start, stop) + statements
            for i, st in enumerate(statements):  # whatever built them, they are checked before they leave
                try:
                    checked_statement(st)
                except TeleprogError as exc:
                    raise InputError(f"statement {start + i + 1}: {exc}") from None
            start_state = self._desk.start
            plan = None if start_state.unknown else plan_or_refuse(outgoing, self._ctx.robot, self._ctx.cell, start_state.q)
            result = editor.submit(start, stop)
            if isinstance(result, Refusal):
                raise RefusedByRule(result)
            for st in outgoing:
                if st.kind == "MODE":
                    self.robot_mode = st.mode
            comm = self.open_communication(outgoing)
            held_before = self._arm.objects.held
            self._advance_start(outgoing, plan)
            arm_events = self._arm.refresh() if self._arm.objects.held != held_before or self._arm.objects.held is not None else []
            self._desk.withdraw_confirmation()
        asyncio.run_coroutine_threadsafe(self.send(robot, comm, outgoing), loop)
        view = self.view()
        self._ctx.bus.emit([SentChanged(sent=view), ProgramChanged(program=self._desk.view()), *arm_events])
        self._arm.follow_start()  # an emptied program: the arm stands where what was sent ends
        self.remote.refresh_predicted()
        return view

    def _regime_prefix(self, statements: list[Statement], start: int, stop: int) -> list[Statement]:
        """What the regime needs sent first (a MODE change), or its refusal (under the lock)."""
        regime = self._modes.regime
        if regime is Regime.QUASI:
            c = self._desk.confirmed_range()
            if c is None or c[0] != 0 or c[1] < stop:
                raise ConflictError(f"quasi-operation regime: preview statements 1..{stop} to their end without warnings before sending")
        if regime is Regime.OPERATION:
            if stop - start != 1:
                raise ConflictError("operation regime: send one statement at a time")
            if any(not s.final for s in self.sent):
                raise ConflictError("operation regime: wait until the previous statement is final")
            st = statements[0]
            if is_action(st) and st.until is None:
                raise ConflictError(f"operation regime: the {st.kind} action needs an UNTIL condition (force or contact)")
            return [SetMode(mode=Mode.FORCE)] if self.robot_mode is not Mode.FORCE else []
        if self.robot_mode is Mode.FORCE and not any(getattr(s, "kind", "") == "MODE" for s in statements[:1]):
            return [SetMode(mode=Mode.POSITION)]
        return []

    def open_communication(self, outgoing: list[Statement]) -> int:
        """Number a new communication and list its statements as sending (under the lock)."""
        self._comms += 1
        now = self._ctx.wall_clock()
        for st in outgoing:
            self.sent.append(Sent(len(self.sent) + 1, st, SentStatus.SENDING, now, self._comms))
        return self._comms

    def _advance_start(self, statements: list[Statement], plan: Plan | None) -> None:
        """The program now starts where the submitted statements are predicted to end; a grasp
        or release among them changes what the virtual gripper holds (under the lock)."""
        start = self._desk.start
        if start.unknown:
            return
        ctx = self._ctx
        if plan is None:
            plan = plan_or_refuse(statements, ctx.robot, ctx.cell, start.q)
        start.q, start.source = plan.q_final.copy(), "predicted"
        if plan.after_task is not None or plan.refusal is not None:
            start.unknown = True
        for segment in plan.segments:
            if isinstance(segment.statement, TaskCall):
                call = segment.statement
                self._arm.objects.apply_task(call.name, call.args, world_T_tcp(ctx.robot, segment.q_start, ctx.frames))

    async def send(self, robot: RobotLink, comm: int, statements: list[Statement]) -> None:
        """One communication over the link; its answer numbers the statements."""
        t0 = self._ctx.clock()
        # a round trip counts only if the link stayed up throughout (else it includes the outage)
        was_up, reconnects = robot.connected.is_set(), robot.reconnects
        try:
            numbers = await robot.submit(statements)
        except RobotRestarted as exc:  # on_robot_restart marked the numbered ones already
            self.mark_unknown([s for s in self.sent if s.comm == comm], str(exc))
            return
        except TeleprogError as exc:  # CommunicationRejected
            self.finish_communication(comm, SentStatus.REJECTED, str(exc))
            self._ctx.bus.emit([Notice(level="error", message=str(exc))])
            return
        except Exception as exc:  # noqa: BLE001 - never let a send die silently
            log.exception("submission %d failed", comm)
            self._ctx.bus.emit([Notice(level="error", message=f"submission failed: {exc}")])
            return
        if was_up and robot.connected.is_set() and robot.reconnects == reconnects:
            self.note_round_trip(self._ctx.clock() - t0)
        with self._ctx.lock:
            items = [s for s in self.sent if s.comm == comm]
            now = self._ctx.wall_clock()
            for s, number in zip(items, numbers):
                s.number, s.answered_at = number, now
                if s.status is SentStatus.SENDING:
                    s.status = SentStatus.RECEIVED
                self._by_number[number] = s
                for report in self._early.pop(number, []):
                    self._apply_report(s, report)
        self._ctx.bus.emit([SentChanged(sent=self.view())])
        self.remote.refresh_predicted()

    def finish_communication(self, comm: int, status: SentStatus, reason: str) -> None:
        """Every statement of a communication ends with ``status`` (the robot refused it, or it
        was never sent); what was predicted did not happen, so the robot's state is the truth."""
        with self._ctx.lock:
            now = self._ctx.wall_clock()
            for s in self.sent:
                if s.comm == comm:
                    s.status, s.reason, s.finished_at = status, reason, now
            self._desk.start.unknown = True
        self._ctx.bus.emit([SentChanged(sent=self.view())])

    # -- reports -------------------------------------------------------------------------------
    def on_report(self, report: StatusReport) -> None:
        """A ``StatusReport`` from the robot (on the client's loop; a replay may call it too)."""
        with self._ctx.lock:
            s = self._by_number.get(report.number)
            if s is None:
                self._early.setdefault(report.number, []).append(report)
                return
            self._apply_report(s, report)
            final = s.final
        self._ctx.bus.emit([SentChanged(sent=self.view())])
        if final:
            for follow_up in (self._arm.follow_start, self.remote.refresh_predicted, self.remote.check_divergence):
                try:
                    follow_up()
                except Exception:  # noqa: BLE001 - the report is taken; a derived view must not undo that
                    log.exception("after the report of statement %d: %s failed", report.number, follow_up.__name__)

    def on_robot_restart(self, restart: SessionRestart) -> None:
        """The robot began a new session: every numbered statement without a final status is
        unknown now, and robot numbers start again."""
        with self._ctx.lock:
            # one still sending learns its fate from its own submission (RobotRestarted in send)
            numbered = list(self._by_number.values())
            self._by_number.clear()
            self._early.clear()
        self.mark_unknown(numbered, restart.describe())
        self._ctx.bus.emit([Notice(level="error", message=restart.describe()), LinkChanged(link=self.link.view())])

    def mark_unknown(self, items: list[Sent], reason: str) -> None:
        with self._ctx.lock:
            now = self._ctx.wall_clock()
            changed = False
            for s in items:
                if not s.final:
                    s.status, s.reason, s.finished_at = SentStatus.UNKNOWN, reason, now
                    changed = True
            if changed:
                self._desk.start.unknown = True  # the robot's state is the truth now
        if changed:
            self._ctx.bus.emit([SentChanged(sent=self.view())])
            self.remote.refresh_predicted()

    def _apply_report(self, s: Sent, report: StatusReport) -> None:
        status = SentStatus(report.state.value)
        now = self._ctx.wall_clock()
        if status is SentStatus.RUNNING and s.started_at is None:
            s.started_at = now
        if status in FINAL_SENT:
            s.finished_at = now
            if s.started_at is None:
                s.started_at = now
            self.remote.take_report(s.statement if status is SentStatus.DONE else None, report)
            if status is not SentStatus.DONE:
                self._desk.start.unknown = True  # the robot did not end where predicted
        if not s.final:
            s.status = status
        s.reason = report.reason or s.reason
