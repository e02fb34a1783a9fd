"""The telerobot without sockets or clocks: the command receiver wired to the executor.

``RobotCore`` takes what arrives on the command channel (text messages and binary units), feeds
accepted statements to the executor's buffer, applies recovery commands, and turns every status
change of the executor into a numbered status report. ``tick()`` advances the executor by one
servo period and says what to send now (reports, heartbeats, a halt). The asyncio service
(``robot_sim.service``) calls these from its socket handlers and its servo loop; tests call them
directly in virtual time.

Liveness (``shared.wire.liveness``): once a console has said hello, the robot sends a heartbeat
every ``heartbeat_s`` and counts anything arriving from the console as heard. When nothing has
arrived for longer than ``heartbeat_s + silence_limit_s`` (the console or the link frozen, or the
connection closed and no console back within that time) and a statement runs or waits, the robot
makes a controlled stop: STOPPED, the arm holding where it is, the buffer held, a ``halted``
message queued for the console and ``Welcome.halted`` set until the operator's ``resume`` (or
``skip``/``abort``). An idle robot with an empty buffer has nothing to stop; a statement that
arrives later comes from a live console and runs. A reconnect within the limit changes nothing:
the current statement goes on, and nothing new starts while no console is connected.

Nothing that arrives can end the process: a message the core cannot handle is answered with a
non-final ``rejected``; an error escaping a servo tick is logged with its traceback, the arm holds
(FAULT, buffer held) and a ``halted`` message with cause ``internal_error`` is sent.
"""

from __future__ import annotations

import itertools
import logging
import uuid
from collections import OrderedDict

from pydantic import BaseModel

from robot_sim.executor import Executor
from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S, HEARTBEAT_INTERVAL_S, SilenceWatch
from shared.language.formatter import format_statement
from shared.wire.messages import (
    MAX_HELD_LISTED,
    MAX_HELD_TEXT,
    MAX_RAN_LISTED,
    WELCOME_BUDGET_BYTES,
    MAX_TEXT,
    AbortFlush,
    HaltCause,
    Halted,
    HeldStatement,
    Heartbeat,
    Rejected,
    RejectReason,
    Resume,
    RobotSnapshot,
    RobotState,
    SkipCurrent,
    StatementState,
    Stop,
    Welcome,
)
from shared.language.statements import Statement
from shared.wire.session import CommandReceiver, ReceiverStep
from shared.wire.telemetry import TelemetryFrame, encode_frame

log = logging.getLogger(__name__)


class RobotCore:
    """One robot: receiver (numbering, idempotency, replay) plus executor (motion, status)."""

    def __init__(
        self,
        executor: Executor,
        session_id: str | None = None,
        heartbeat_s: float = HEARTBEAT_INTERVAL_S,
        silence_limit_s: float = DEFAULT_SILENCE_LIMIT_S,
    ) -> None:
        self.executor = executor
        self.receiver = CommandReceiver(session_id or uuid.uuid4().hex[:16], room=executor.room)
        self.connected = False  # a console connection is open
        self.greeted = False  # ... and has said hello: reports may flow on it
        self.frame_number = 0
        self.heartbeat_s = heartbeat_s
        self.silence_limit_s = silence_limit_s
        self.watch = SilenceWatch(interval=heartbeat_s, limit=silence_limit_s)
        self._heartbeats = 0
        self._next_heartbeat = 0.0
        self._unsent: list[Halted] = []  # halts made while no console was greeted
        self._statements: dict[int, Statement] = {}  # number -> statement, from acceptance to its final report
        self._ran: OrderedDict[int, tuple[Statement, StatementState]] = OrderedDict()  # the newest finished ones

    # -- command channel ----------------------------------------------------------------------
    def connect(self) -> None:
        """A console connection opened. Nothing flows on it until its ``hello``: status reports
        produced before then are replayed after the ``welcome``, so the client never sees a
        newer report before the older ones it missed."""
        self.connected = True

    def disconnect(self) -> None:
        self.connected = False
        self.greeted = False
        self.receiver.disconnect()
        self.executor.hold_queue = True
        log.warning(
            "console connection lost: starting nothing new; the arm stops if no console is back within %.1f s",
            self.watch.threshold,
        )

    def on_text(self, text: str | bytes) -> list[BaseModel]:
        try:
            step = self.receiver.on_text(text)
            if any(isinstance(r, Welcome) for r in step.replies):
                self.greeted = True
                self.executor.hold_queue = False
                self._heartbeats = 0
                self._next_heartbeat = self.executor.time + self.heartbeat_s
                step.replies[:] = [self._welcome(r) if isinstance(r, Welcome) else r for r in step.replies]
                step.replies += self._unsent
                self._unsent = []
            if self.greeted:
                self.watch.heard(self.executor.time)
            return self._apply(step)
        except Exception as exc:  # noqa: BLE001 - the last-resort boundary of a message handler
            return [self._refuse_internal("message", exc)]

    def on_unit(self, data: bytes) -> list[BaseModel]:
        try:
            if self.greeted:
                self.watch.heard(self.executor.time)
            return self._apply(self.receiver.on_unit(data))
        except Exception as exc:  # noqa: BLE001 - the last-resort boundary of a message handler
            return [self._refuse_internal("unit", exc)]

    def _refuse_internal(self, what: str, exc: Exception) -> Rejected:
        log.exception("internal error while handling a %s", what)
        return Rejected(
            reason=RejectReason.BAD_MESSAGE, final=False,
            detail=f"internal error while handling this {what}: {type(exc).__name__}: {str(exc)[:300]}",
        )

    def _welcome(self, welcome: Welcome) -> Welcome:
        return welcome.model_copy(update={
            "heartbeat_s": self.heartbeat_s,
            "silence_limit_s": self.silence_limit_s,
            "halted": self.executor.halted[:MAX_TEXT] if self.executor.halted else None,
            "holds": (account := self._account())[0],
            "holds_total": len(self.executor.queue) + (self.executor.current is not None),
            "ran": account[1],
            "numbered": self.receiver.next_number - 1,
        })

    def _account(self) -> tuple[list[HeldStatement], list[HeldStatement]]:
        """What the robot holds (running first, then queued in order) and the newest it finished
        (oldest first), for a console that connects, restarted or not, to show before anybody
        resumes. Both lists are cut where the welcome would pass ``WELCOME_BUDGET_BYTES`` (the
        held ones come first: they are what a resume runs)."""
        ex = self.executor
        held = [] if ex.current is None else [(*ex.current, "running")]
        held += [(n, s, "received") for n, s in itertools.islice(ex.queue, MAX_HELD_LISTED - len(held))]
        budget = [WELCOME_BUDGET_BYTES]
        holds = self._listed(held, budget)
        ran = self._listed([(n, s, state.value) for n, (s, state) in reversed(self._ran.items())], budget)
        return holds, ran[::-1]

    def _listed(self, items, budget: list[int]) -> list[HeldStatement]:
        out = []
        for number, statement, state in items:
            text = format_statement(statement)
            budget[0] -= 3 * len(text) + 150  # its text, its JSON form (about as long) and the fields around them, with room to spare
            if budget[0] < 0:
                break
            out.append(HeldStatement(number=number, text=_cut(text, MAX_HELD_TEXT), running=state == "running",
                                     client_id=self.receiver.senders.get(number), state=state, statement=statement))
        return out

    def _apply(self, step: ReceiverStep) -> list[BaseModel]:
        out: list[BaseModel] = list(step.replies)
        for number, statement in step.accepted:
            self._statements[number] = statement
            self.executor.enqueue(number, statement)
        for cmd in step.recoveries:
            if isinstance(cmd, Stop):
                applied, detail = self.executor.stop()
            elif isinstance(cmd, Resume):
                applied, detail = self.executor.resume()
            elif isinstance(cmd, SkipCurrent):
                applied, detail = self.executor.skip(cmd.number)
            elif isinstance(cmd, AbortFlush):
                applied, detail = self.executor.abort()
            else:  # pragma: no cover - the receiver only passes the four kinds
                applied, detail = False, f"unknown recovery {cmd!r}"
            log.info("recovery %s #%d: %s", cmd.type, cmd.command_id, detail)
            # reports the command caused (skipped, aborted) go out before its acknowledgement
            out += self._reports(self.executor.drain_events())
            out.append(self.receiver.ack(cmd, applied, detail, self.executor.snapshot()))
        return out

    # -- servo ----------------------------------------------------------------------------------
    def tick(self) -> list[BaseModel]:
        """One servo period; returns what to send now, in order (status reports, a halt, a
        heartbeat). Reports made while no greeted console is connected are kept by the receiver
        and replayed later; a halt is kept and sent after the next welcome."""
        out: list[BaseModel] = []
        try:
            self._check_silence(out)
            out += self._reports(self.executor.tick())
            if (own := self.executor.take_own_fault()) is not None:
                self._halted(out, *own)
        except Exception as exc:  # noqa: BLE001 - the last-resort boundary of the servo loop
            log.exception("internal error in the servo tick: holding the arm")
            reason = f"internal error in the servo loop: {type(exc).__name__}: {str(exc)[:300]}; the arm holds"
            try:
                self.executor.internal_fault(reason)
                out += self._reports(self.executor.drain_events())
            except Exception:  # noqa: BLE001 - even the report failed: hold without it
                log.exception("cannot report the internal error's statement")
                self.executor.state = RobotState.FAULT
            self._halted(out, HaltCause.INTERNAL_ERROR, reason)
        if self.greeted and self.executor.time + 1e-9 >= self._next_heartbeat:
            out.append(Heartbeat(seq=self._heartbeats))
            self._heartbeats += 1
            self._next_heartbeat += self.heartbeat_s
        return out if self.greeted else []

    def skip_idle(self, until: float) -> bool:
        """Virtual time only: move an idle robot's clock on to ``until`` without servo ticks, as if
        it had ticked with nothing to run (no statement running or waiting, nothing held for the
        operator). On physics only while the world is at rest (``PhysicsWorld.asleep``): a world
        still settling is stepped. Its heartbeats of the skipped periods are not sent (nobody hears them in virtual
        time), the next one is due as if it had. False, and nothing changes, when it is not idle."""
        ex = self.executor
        if ex.busy or ex.state is not RobotState.IDLE or until <= ex.time:
            return False
        if ex.physical:
            if not ex.world.asleep:
                return False  # something still moves: the periods are stepped
            ex.world.advance(until - ex.time)  # at rest: the clock moves on, no physics step
        ex.time = until
        while self._next_heartbeat <= until:
            self._next_heartbeat += self.heartbeat_s
            self._heartbeats += 1
        return True

    def _check_silence(self, out: list[BaseModel]) -> None:
        now = self.executor.time
        if not (self.watch.silent(now) and self.executor.busy):
            return
        if self.executor.state not in (RobotState.IDLE, RobotState.RUNNING):
            return  # already holding
        age = self.watch.age(now) or 0.0
        detail = (
            f"no message from the console for {age:.1f} s (limit {_seconds(self.silence_limit_s)} s beyond the "
            f"{_seconds(self.heartbeat_s)} s heartbeat)"
        )
        if self.executor.halt(detail):
            self._halted(out, HaltCause.SILENCE, detail)

    def _halted(self, out: list[BaseModel], cause: HaltCause, detail: str) -> None:
        message = Halted(cause=cause, detail=detail[:MAX_TEXT], robot=self._snapshot())
        if self.greeted:
            out.append(message)
        else:
            self._unsent.append(message)

    def _snapshot(self) -> RobotSnapshot | None:
        try:
            return self.executor.snapshot()
        except Exception:  # noqa: BLE001 - a halt is reported even when the state cannot be
            log.exception("cannot take the robot's snapshot")
            return None

    def _reports(self, events) -> list[BaseModel]:
        out = []
        for e in events:
            if e.state.final and (statement := self._statements.pop(e.number, None)) is not None:
                self._ran[e.number] = (statement, e.state)
                while len(self._ran) > MAX_RAN_LISTED:
                    self._ran.popitem(last=False)
            robot = e.snapshot if e.state is not StatementState.RUNNING else None
            out.append(self.receiver.report(e.number, e.state, e.reason, robot, robot_time=self.executor.time))
        return out

    # -- telemetry ------------------------------------------------------------------------------
    def telemetry(self) -> bytes:
        """The current state as one fixed-size binary frame."""
        snap = self.executor.snapshot()
        state = snap.state if self.connected else RobotState.DISCONNECTED
        self.frame_number += 1
        return encode_frame(
            TelemetryFrame(
                time=self.executor.time,
                frame=self.frame_number,
                state=state,
                mode=snap.mode,
                statement=self.executor.current_number,
                q=snap.q,
                position=snap.base_p_tool,
                rpy=snap.tool_rpy,
                gripper=snap.gripper,
                wrench=snap.wrench,
            )
        )


def _seconds(value: float) -> str:
    """A setting in seconds as people write it: 1.0, 0.2, 0.05."""
    return f"{value:.1f}" if round(value, 1) == value else f"{value:g}"


def _cut(text: str, limit: int) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."
