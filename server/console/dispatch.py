"""Dispatch (thesis §4.2.1-4.2.2): statements leave the program for the robot, get the robot's
numbers, and move through their statuses as its reports arrive.

What goes out is exactly the lines of the program the operator submitted: the console never
sends a statement that is not a line. Where the regime needs the arm in another control mode,
the console puts the MODE statement into the program as a line of its own (marked as added by
the console, with its reason, deletable like any line) and refuses the submission once: "submit
needs MODE FORCE first: added as line N, submit again".

``submit`` applies the regime's rules:

* free motion (online) and quasi-operation (offline): actions run in position mode, where any
  contact past the robot's contact limit stops them. An action that would run in force mode only
  because an earlier submission left the robot there gets a ``MODE POSITION`` line before it;
  a MODE statement the operator put in the range before the action is the operator's choice and
  stands. In quasi-operation the range must also have been previewed to its end without warnings.
* operation (single step, near contact): one step at a time, each after the previous one is
  final. A step is at most one motion (an action, or a task that moves the arm), with any
  parameter statements (SPEED, MODE, EVENT) around it. The motion must be guarded against contact
  it does not expect, in one of two ways: an action meant to touch carries an UNTIL (force or
  contact) and runs in force mode (a ``MODE FORCE`` line before it when the robot is not in force
  mode); an action not meant to touch has no UNTIL, the model must show its whole path clear of
  contact (the preview's check: no arm contact, no joint range left), and it runs in position mode
  (a ``MODE POSITION`` line when needed), where an unexpected contact stops it at the contact
  limit. Tasks bring their own guarding (the robot's force-compliant sub-tasks) and need no mode.
  So the console's own programs pass: the rover placement program (joint moves to poses whose
  clearance the placement search checked) and generated DRAW/DRIVE statements go one step at a
  time, and a contact move the operator wrote carries its UNTIL.

A console line the operator deleted is not put back for the same need: in free and
quasi-operation the statement then goes without it (the operator's choice); in operation the
submission is refused with what to do.

The mode the robot will be in (:attr:`Dispatch.robot_mode`) is predicted from the sent list: the
last MODE statement since the robot's session began that was not dropped (rejected, skipped,
aborted, unknown), else the mode telemetry reports, else position.

The statements leave the program at once and join the sent list as ``sending``; the send itself
runs on the robot client's loop and is never waited for. The program then starts where the sent
statements are predicted to end (and a grasp or release among them changes what the virtual
gripper holds). Reports that arrive before their numbers are kept until the numbers come. A robot
that began a new session leaves every unanswered statement ``unknown``.
"""

from __future__ import annotations

import asyncio
import logging
from typing import TYPE_CHECKING

import numpy as np

from server.console.context import ConsoleContext
from server.console.enums import FINAL_SENT, Regime, SentStatus
from server.console.errors import (
    ConflictError,
    ConsoleLineAdded,
    NotConnectedError,
    RefusedByRule,
)
from server.console.events import (
    LinkChanged,
    Notice,
    ProgramChanged,
    RangeSubmitted,
    SentChanged,
)
from server.console.robot_account import AccountBooks
from server.console.sent import Sent
from server.console.robot_seam import RobotLink
from server.console.statement_checks import statement_refusal, statement_text
from server.console.views import Caller, SentListView
from server.robot_client import RobotRestarted
from shared.errors import InputError, TeleprogError
from shared.language.statements import Mode, SetMode, Statement, TaskCall, is_action
from shared.language.task_rule import moves_arm
from shared.motion import Plan
from shared.motion.plan_check import plan_or_refuse
from shared.program.editor import Refusal
from shared.robots.jog import world_T_tcp
from shared.wire.messages import ControlMode, StatusReport
from shared.wire.session import SessionRestart

if TYPE_CHECKING:
    from server.console.arm import VirtualArm
    from server.console.control import ControlLock
    from server.console.modes import Modes
    from server.console.program_desk import ProgramDesk
    from server.console.ports import LinkRead, RemoteSink

log = logging.getLogger(__name__)

NOT_RUN = frozenset({SentStatus.REJECTED, SentStatus.SKIPPED, SentStatus.ABORTED, SentStatus.UNKNOWN, SentStatus.FAILED})
"""Final statuses of a statement that did not (or may not have) run."""


NO_ROBOT = "no robot is configured for this console (started with --no-robot)"


class Dispatch(AccountBooks):
    """The robot seam, the sent list and the statuses."""

    def __init__(self, ctx: ConsoleContext, control: ControlLock, modes: Modes, desk: ProgramDesk, arm: VirtualArm) -> None:
        self._ctx = ctx
        self._control, self._modes, self._desk, self._arm = control, modes, desk, arm
        self.remote: RemoteSink | None = None  # set by the session
        self.link: LinkRead | None = None  # set by the session
        self.robot: RobotLink | None = None
        self.loop: asyncio.AbstractEventLoop | None = None
        self.url: str | None = None
        self.sent: list[Sent] = []
        self._by_number: dict[int, Sent] = {}
        self._early: dict[int, list[StatusReport]] = {}
        self._comms = 0
        self._session_from = 0  # the sent list's first statement of the robot's current session
        self.history_below = 0  # reports of unknown numbers below this are history (robot_account)
        self.round_trips: list[float] = []

    # -- the seam ------------------------------------------------------------------------------
    def attach(self, robot: RobotLink, loop: asyncio.AbstractEventLoop) -> None:
        """Use ``robot`` on ``loop`` for submissions, recovery and telemetry (once, at start)."""
        with self._ctx.lock:
            self.robot, self.loop, self.url = robot, loop, robot.url
        robot.on_report(self.on_report)
        robot.on_telemetry(self.remote.take_frame, gate=self.remote.gate_frame)
        robot.on_restart(self.on_robot_restart)
        robot.on_account(self.take_account)

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
        """Send ``statements[start:stop]`` (``start`` must be 0) to the robot, under the regime.
        A refusal by a rule is also shown on the line it concerns (``ProgramView.refusal``)."""
        try:
            return self._submit(start, stop, client=client)
        except RefusedByRule as exc:
            self._desk.show_refusal(exc.refusal)
            raise

    def _submit(self, start: int, stop: int, *, client: Caller | str | None = None) -> SentListView:
        try:
            with self._ctx.lock:
                self._control.check(client)
                robot, loop = self.need_robot()
                self._desk.check_not_previewing("submit statements")
                editor = self._desk.editor
                check = editor.state.check_submit(start, stop)
                if check is not None:
                    raise RefusedByRule(check)
                statements = list(editor.state.statements[start:stop])
                for i, st in enumerate(statements):  # whatever built them, they are checked before they leave
                    if (refused := statement_refusal(st)) is not None:  # once per statement object
                        raise InputError(f"statement {start + i + 1}: {refused}")
                self._regime_rules(statements, start, stop)
                self._mode_line(statements, start, stop)  # raises ConsoleLineAdded after adding one
                start_state = self._desk.start
                plan = None if start_state.unknown else self._desk.planned(stop)  # the program's own plan, kept
                result = editor.submit(start, stop)
                if isinstance(result, Refusal):
                    raise RefusedByRule(result)
                self._desk.lines_sent(statements)
                mode_before = self.robot_mode
                comm = self.open_communication(statements)
                if self.robot_mode is not mode_before:
                    self._desk.forget_declined()  # the need for a mode line is a new one now
                held_before = self._arm.objects.held
                start_q = None if start_state.unknown else start_state.q.copy()
                plan = self._advance_start(statements, plan)
                submitted = self._submitted_event(comm, statements, start_q, plan)
                arm_events = self._arm.refresh() if self._arm.objects.held != held_before or self._arm.objects.held is not None else []
                self._desk.withdraw_confirmation()
        except ConsoleLineAdded as exc:
            self._ctx.bus.emit([ProgramChanged(program=self._desk.view()), Notice(level="warning", message=str(exc))])
            raise
        asyncio.run_coroutine_threadsafe(self.send(robot, comm, statements), loop)
        view = self.view()
        self._ctx.bus.emit([submitted, SentChanged(sent=view), ProgramChanged(program=self._desk.view()), *arm_events])
        self._arm.follow_start()  # an emptied program: the arm stands where what was sent ends
        self._ctx.after.post(self.remote.refresh_predicted)  # planned from the robot's arm: not the caller's wait
        return view

    @property
    def robot_mode(self) -> Mode:
        """The mode the robot will be in once what was sent has run (module docstring)."""
        with self._ctx.lock:
            for s in reversed(self.sent[self._session_from:]):
                if isinstance(s.statement, SetMode) and s.status not in NOT_RUN:
                    return s.statement.mode
            frame = self.remote.telemetry if self.remote is not None else None
            return Mode.FORCE if frame is not None and frame.mode is ControlMode.FORCE else Mode.POSITION

    def _regime_rules(self, statements: list[Statement], start: int, stop: int) -> None:
        """The regime's refusals of this range (under the lock); the mode is :meth:`_mode_line`'s."""
        regime = self._modes.regime
        if regime is Regime.QUASI:
            c = self._desk.confirmed_range()
            if c is None or c[0] != 0 or c[1] < stop:
                raise ConflictError(f"quasi-operation regime: preview statements 1..{stop} to their end without warnings before sending")
        if regime is not Regime.OPERATION:
            return
        if any(not s.final for s in self.sent):
            raise ConflictError("operation regime: wait until the previous statement is final")
        motions = [start + i for i, st in enumerate(statements) if moves_arm(st)]
        if len(motions) > 1:
            first = motions[0]
            raise ConflictError(
                f"operation regime: one motion per step; statements {first + 1} and {motions[1] + 1} both move the arm: "
                f"submit statements 1..{motions[1]} first"
            )
        actions = [i for i in motions if is_action(statements[i - start])]
        if actions and statements[actions[0] - start].until is None:
            index = actions[0]
            st = statements[index - start]
            try:
                blocked = self._desk.preview.path_not_clear(start, stop).get(index)
            except TeleprogError as exc:
                blocked = f"it cannot be planned: {exc}"
            if blocked is not None:
                raise ConflictError(
                    f"operation regime: the {st.kind} (statement {index + 1}) has no UNTIL and its path is not clear "
                    f"({blocked}): give it an UNTIL (contact or force) or move clear first"
                )

    def _mode_line(self, statements: list[Statement], start: int, stop: int) -> None:
        """Where an action of the range would run in a mode the regime does not allow, put the MODE
        statement into the program before it and refuse (``ConsoleLineAdded``), once; a line the
        operator took out is not put back (under the lock)."""
        need = self._mode_need(statements, start)
        if need is None:
            return
        index, line, why = need
        number = self._desk.add_console_line(index, line, why, self._modes.regime)
        raise ConsoleLineAdded(
            f"submit needs MODE {line.mode.value.upper()} first ({why}): added as line {number}, submit again"
            f" (statements 1..{stop + 1})"
        )

    def _mode_need(self, statements: list[Statement], start: int) -> tuple[int, SetMode, str] | None:
        """The MODE line the range needs and where (program index, statement, why), or None; a
        deleted line the operation regime cannot go without is a ``ConflictError`` (under the lock)."""
        regime = self._modes.regime
        mode, set_here = self.robot_mode, False
        for i, st in enumerate(statements):
            if isinstance(st, SetMode):
                mode, set_here = st.mode, True
                continue
            if not is_action(st):
                continue
            if regime is Regime.OPERATION:
                need = Mode.FORCE if st.until is not None else Mode.POSITION
                why = (f"operation regime: the {st.kind} with UNTIL runs in force mode" if need is Mode.FORCE
                       else f"operation regime: the {st.kind} without UNTIL runs in position mode, where any contact stops it")
            elif not set_here:
                need = Mode.POSITION
                why = f"{regime.value} regime: the robot is left in force mode; the {st.kind} runs in position mode"
            else:
                continue
            if mode is need:
                continue
            line = SetMode(mode=need)
            if self._desk.declined(line, regime):
                if regime is Regime.OPERATION:
                    raise ConflictError(
                        f"{why}: the MODE {need.value.upper()} line the console added was deleted; insert MODE "
                        f"{need.value.upper()} before statement {start + i + 1}, or leave the operation regime"
                    )
                return None  # the operator's choice: it goes in the mode it is in
            return start + i, line, why
        return None

    # -- what submit would say, without sending (server.console.readiness reads these) ----------
    def confirmed_through(self, stop: int) -> bool:
        """The quasi regime's predicate: statements 1..``stop`` were previewed to their end
        without warnings and are unchanged since."""
        with self._ctx.lock:
            c = self._desk.confirmed_range()
            return c is not None and c[0] == 0 and c[1] >= stop

    def previous_final(self) -> bool:
        """The operation regime's predicate: every statement sent has its final status."""
        with self._ctx.lock:
            return all(s.final for s in self.sent)

    def refusal(self, start: int, stop: int, *, regime: bool = True) -> str | None:
        """The sentence ``submit(start, stop)`` would refuse with now, or None: its own checks in
        its order (a robot, no preview running, the editor's range rule, the regime's rules, each
        statement's check, a MODE line the regime needs), nothing sent and nothing changed. ``regime=False`` leaves the
        regime's rule out (what "Preview and submit" checks before it previews). The control
        lock is not asked: this is what the rules say, whoever asks."""
        with self._ctx.lock:
            try:
                self.need_robot()
                self._desk.check_not_previewing("submit statements")
                editor = self._desk.editor
                check = editor.state.check_submit(start, stop)
                if check is not None:
                    return check.message
                statements = list(editor.state.statements[start:stop])
                for i, st in enumerate(statements):
                    if (refused := statement_refusal(st)) is not None:
                        return f"statement {start + i + 1}: {refused}"
                if regime:
                    self._regime_rules(statements, start, stop)
                    need = self._mode_need(statements, start)
                    if need is not None:
                        index, line, why = need
                        return (f"MODE {line.mode.value.upper()} is needed before statement {index + 1} ({why}): "
                                "Submit adds it as a line first; submit again to send")
            except TeleprogError as exc:
                return exc.refusal.message if isinstance(exc, RefusedByRule) else str(exc)
        return None

    def open_communication(self, outgoing: list[Statement]) -> int:
        """Number a new communication and list its statements as sending (under the lock)."""
        self._comms += 1
        now = self._ctx.wall_clock()
        for st in outgoing:
            self.sent.append(Sent(len(self.sent) + 1, st, SentStatus.SENDING, now, self._comms))
        return self._comms

    def _submitted_event(self, comm: int, statements: list[Statement], start_q: np.ndarray | None, plan: Plan | None) -> RangeSubmitted:
        """What a recording keeps of a submission: the statements and the console's plan of them,
        sampled at the preview's spacing (under the lock)."""
        ids = [s.id for s in self.sent if s.comm == comm]
        texts = [statement_text(st) for st in statements]
        if start_q is None or plan is None:
            return RangeSubmitted(ids=ids, texts=texts)
        dt = self._ctx.settings.preview_dt
        ts = np.append(np.arange(0.0, plan.duration, dt), plan.duration)
        samples = plan.sample(ts)
        return RangeSubmitted(
            ids=ids, texts=texts, start_q=[float(v) for v in start_q], plan_t=ts.tolist(), plan_q=samples.q.tolist(),
            statement_starts=np.asarray(plan.start_times, dtype=float).tolist(),
            statement_ends=(np.asarray(plan.start_times, dtype=float) + plan.durations).tolist(),
            complete=plan.ok and plan.after_task is None and len(plan.segments) == len(statements),
        )

    def _advance_start(self, statements: list[Statement], plan: Plan | None) -> Plan | None:
        """The program now starts where the submitted statements are predicted to end; a grasp
        or release among them changes what the virtual gripper holds (under the lock). Returns
        the plan from the start (None when the start is unknown)."""
        start = self._desk.start
        if start.unknown:
            return None
        ctx = self._ctx
        if plan is None:
            plan = plan_or_refuse(statements, ctx.robot, ctx.cell, start.q, self._arm.task_objects())
        start.q, start.source = plan.q_final.copy(), "predicted"
        if plan.after_task is not None or plan.refusal is not None:
            start.unknown = True
        for segment in plan.segments:
            if isinstance(segment.statement, TaskCall):
                call = segment.statement
                self._arm.objects.apply_task(call.name, call.args, world_T_tcp(ctx.robot, segment.q_start, ctx.frames))
        return plan

    async def send(self, robot: RobotLink, comm: int, statements: list[Statement]) -> None:
        """One communication over the link; its answer numbers the statements. Runs on the robot
        client's loop and only awaits the robot: what the answer changes is done on the console's
        ``after`` thread (the loop never waits for the session's lock)."""
        t0 = self._ctx.clock()
        # a round trip counts only if the link stayed up throughout (else it includes the outage)
        was_up, reconnects = robot.connected.is_set(), robot.reconnects
        try:
            numbers = await robot.submit(statements)
        except Exception as exc:  # noqa: BLE001 - every failure is told; none ends the loop
            self._ctx.after.post(self._send_failed, comm, exc)
            return
        round_trip = None
        if was_up and robot.connected.is_set() and robot.reconnects == reconnects:
            round_trip = self._ctx.clock() - t0
        self._ctx.after.post(self._answered, comm, numbers, round_trip, self._ctx.wall_clock())

    def _send_failed(self, comm: int, exc: Exception) -> None:
        if isinstance(exc, RobotRestarted):  # on_robot_restart marked the numbered ones already
            self.mark_unknown([s for s in self.sent if s.comm == comm], str(exc))
        elif isinstance(exc, TeleprogError):  # CommunicationRejected
            self.finish_communication(comm, SentStatus.REJECTED, str(exc))
            self._ctx.bus.emit([Notice(level="error", message=str(exc))])
        else:
            log.error("submission %d failed: %s", comm, exc, exc_info=exc)
            self._ctx.bus.emit([Notice(level="error", message=f"submission failed: {exc}")])

    def _answered(self, comm: int, numbers: tuple[int, ...], round_trip: float | None, now: float) -> None:
        """The robot numbered communication ``comm`` (on the ``after`` thread)."""
        if round_trip is not None:
            self.note_round_trip(round_trip)
        with self._ctx.lock:
            items = [s for s in self.sent if s.comm == comm]
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
        """A ``StatusReport`` from the robot (on the robot client's delivery thread; a replay may call it too)."""
        with self._ctx.lock:
            s = self._by_number.get(report.number)
            if s is None:
                if report.number >= self.history_below:  # else: before this console, not in the account
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
            self._session_from = len(self.sent)  # the new session starts in position mode
            self._by_number.clear()
            self._early.clear()
            self.history_below = 0
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
            s.started_at, s.robot_started_at = now, report.robot_time
        if status in FINAL_SENT:
            s.finished_at, s.robot_finished_at = now, report.robot_time
            if s.started_at is None:
                s.started_at, s.robot_started_at = now, report.robot_time
            self.remote.take_report(s.statement if status is SentStatus.DONE else None, report)
            if status is not SentStatus.DONE:
                self._desk.start.unknown = True  # the robot did not end where predicted
        if not s.final:
            s.status = status
        s.reason = report.reason or s.reason
