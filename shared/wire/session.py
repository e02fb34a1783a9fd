"""The two ends of the command channel as sans-I/O state machines.

``CommandReceiver`` is the robot's end: it takes the bytes of units and the texts of messages,
assembles communications, numbers their statements, answers, logs status reports and replays what
a reconnecting client missed. ``CommandSender`` is the console's end: it cuts programs into units,
keeps them until answered, and after a reconnect works out what to send again. Neither touches a
socket or a clock, so the exactly-once argument in ``shared.wire.messages`` can be tested by
feeding them any interleaving of losses and reconnects.
"""

from __future__ import annotations

import logging
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field

from pydantic import BaseModel

from shared.language.statements import Statement
from shared.wire.messages import (
    CLIENT_TYPES,
    FINAL_STATES,
    PROTOCOL_VERSION,
    AbortFlush,
    Accepted,
    Answer,
    Heartbeat,
    Hello,
    RecoveryAck,
    Recovery,
    Rejected,
    RejectReason,
    Resume,
    RobotSnapshot,
    SkipCurrent,
    StatementState,
    StatusReport,
    Stop,
    Welcome,
    decode_message,
)
from shared.wire.units import CommandUnit, decode_unit, split_into_units

log = logging.getLogger(__name__)

MAX_COMM_STATEMENTS = 100_000
"""Most statements one communication may hold (the receiver's buffer limit per communication)."""
KEPT_ANSWERS = 4096
"""Answers kept per client for re-delivery after a reconnect."""


@dataclass
class ReceiverStep:
    """What one input produced: messages for this connection, statements for the robot's buffer,
    recovery commands to apply (each new one once; call ``CommandReceiver.ack`` after applying)."""

    replies: list[BaseModel] = field(default_factory=list)
    accepted: list[tuple[int, Statement]] = field(default_factory=list)
    recoveries: list[Recovery] = field(default_factory=list)


@dataclass
class _ClientState:
    last_answered: int = 0
    units: list[CommandUnit] = field(default_factory=list)  # units held of communication last_answered + 1
    answers: OrderedDict[int, Answer] = field(default_factory=OrderedDict)
    last_applied_command: int = 0
    acks: OrderedDict[int, RecoveryAck] = field(default_factory=OrderedDict)
    stops: OrderedDict[int, None] = field(default_factory=OrderedDict)  # stop ids applied (any id)


class CommandReceiver:
    """The robot's end of the command channel (one per robot process, across connections).

    Send ``replies`` (and the reports from ``report``) on the current connection in the order they
    were produced, through one writer: the client relies on report order.

    ``room`` (optional) says how many statements the robot's buffer can take now: a communication
    with more is answered ``buffer_full`` (final: nothing of it runs).

    Recovery command ids: a ``stop`` is passed on whatever its id, and even before ``hello``, so
    no id can lock it out; a repeat of a stop id already applied is acknowledged again, not
    applied again, and a stop advances ``last_applied_command`` only when its id is the next one.
    ``resume``, ``skip`` and ``abort`` must carry the next id: a repeat (id not above the last
    applied) is acknowledged again, an id that jumps ahead is refused and changes nothing.
    """

    def __init__(
        self,
        session_id: str,
        first_number: int = 1,
        max_comm_statements: int = MAX_COMM_STATEMENTS,
        room: Callable[[], int] | None = None,
    ) -> None:
        self.session_id = session_id
        self.next_number = first_number
        self.max_comm_statements = max_comm_statements
        self.room = room
        self.reports: list[StatusReport] = []
        self._clients: dict[str, _ClientState] = {}
        self._client: str | None = None  # client bound to the current connection
        self.senders: dict[int, str] = {}  # statement number -> the client that sent it

    # -- connection ---------------------------------------------------------------------------

    @property
    def greeted(self) -> bool:
        """A client has said hello on the current connection."""
        return self._client is not None

    def disconnect(self) -> None:
        """The connection ended; state is kept for the client's return."""
        self._client = None

    def on_text(self, text: str | bytes) -> ReceiverStep:
        msg = decode_message(text, allowed=CLIENT_TYPES)
        if isinstance(msg, Rejected):  # the robot's own refusal of the message (never an echo)
            return ReceiverStep(replies=[msg.model_copy(update={"final": False})])
        if isinstance(msg, Hello):
            return self._hello(msg)
        if isinstance(msg, Heartbeat):
            return ReceiverStep()  # its arrival is all it says (the caller counts it as heard)
        if isinstance(msg, (Stop, Resume, SkipCurrent, AbortFlush)):
            return self._recovery(msg)
        return ReceiverStep(replies=[Rejected(
            reason=RejectReason.BAD_MESSAGE, final=False, detail=f"the robot does not take {msg.type!r} messages"
        )])

    def _hello(self, hello: Hello) -> ReceiverStep:
        if hello.protocol != PROTOCOL_VERSION:
            return ReceiverStep(replies=[Rejected(
                reason=RejectReason.PROTOCOL, final=False,
                detail=f"protocol {hello.protocol} not supported; this robot speaks {PROTOCOL_VERSION}",
            )])
        if hello.session_id is not None and hello.session_id != self.session_id:
            # the client's counters belong to an earlier robot process: it has seen nothing of ours
            log.info("hello of %s from robot session %s (this is %s): replaying everything",
                     hello.client_id, hello.session_id, self.session_id)
            hello = hello.model_copy(update={"last_answered_comm": 0, "last_report_seq": 0, "last_acked_command": 0})
        client = self._clients.setdefault(hello.client_id, _ClientState())
        if hello.new_process:
            self._forget_dead_process(hello.client_id, client)
        self._client = hello.client_id
        step = ReceiverStep()
        step.replies.append(
            Welcome(
                session_id=self.session_id,
                last_answered_comm=client.last_answered,
                units_held=len(client.units),
                last_applied_command=client.last_applied_command,
                last_report_seq=len(self.reports),
            )
        )
        step.replies += [a for c, a in client.answers.items() if c > hello.last_answered_comm]
        step.replies += [a for c, a in client.acks.items() if c > hello.last_acked_command]
        step.replies += self.reports[hello.last_report_seq :]
        return step

    @staticmethod
    def _forget_dead_process(client_id: str, client: _ClientState) -> None:
        """A new process under a kept identity has sent nothing yet, and numbers on from the
        welcome's counters (``CommandSender.adopt``): what the earlier process left beyond them
        is forgotten, so none of the new ids reads as a repeat. That is its half-sent
        communication (never numbered, never run) and the stops it had applied out of turn (ids
        past ``last_applied_command``; the new process's own stop with such an id must apply)."""
        ahead = [i for i in client.stops if i > client.last_applied_command]
        if client.units or ahead:
            log.info("hello of %s from a new process: dropping %d unit(s) of its unfinished communication %d "
                     "and %d stop id(s) past %d", client_id, len(client.units), client.last_answered + 1, len(ahead),
                     client.last_applied_command)
        client.units = []
        for i in ahead:
            del client.stops[i]
            client.acks.pop(i, None)

    # -- units ---------------------------------------------------------------------------------

    def on_unit(self, data: bytes) -> ReceiverStep:
        if self._client is None:
            return ReceiverStep(replies=[Rejected(reason=RejectReason.NO_SESSION, detail="send hello before units", final=False)])
        client = self._clients[self._client]
        unit = decode_unit(data)
        expected = client.last_answered + 1
        comm_id = unit.comm_id
        if comm_id is None:  # unreadable header: nothing to tie it to
            return ReceiverStep(replies=[unit.model_copy(update={"final": False})])
        if comm_id < expected:  # a repeat of an answered communication
            end = unit.end if isinstance(unit, CommandUnit) else False
            answer = client.answers.get(comm_id)
            return ReceiverStep(replies=[answer] if end and answer is not None else [])
        if comm_id > expected:
            return ReceiverStep(replies=[Rejected(
                comm_id=comm_id, seq=unit.seq, reason=RejectReason.OUT_OF_SEQUENCE, final=False,
                detail=f"communication {comm_id} arrived while {expected} is open",
            )])
        offset = sum(len(u.statements) for u in client.units)
        if isinstance(unit, Rejected):
            if unit.statement_index is not None:
                unit = unit.model_copy(update={"statement_index": offset + unit.statement_index})
            return self._answer(client, unit)
        if unit.seq < len(client.units):  # a repeat of a unit already held
            return ReceiverStep()
        if unit.seq > len(client.units):
            return self._answer(client, Rejected(
                comm_id=comm_id, seq=unit.seq, reason=RejectReason.OUT_OF_SEQUENCE,
                detail=f"unit {unit.seq} arrived while unit {len(client.units)} was expected",
            ))
        if offset + len(unit.statements) > self.max_comm_statements:
            return self._answer(client, Rejected(
                comm_id=comm_id, seq=unit.seq, reason=RejectReason.TOO_LARGE,
                detail=f"communication over {self.max_comm_statements} statements",
            ))
        client.units.append(unit)
        if not unit.end:
            return ReceiverStep()
        statements = [s for u in client.units for s in u.statements]
        room = self.room() if self.room is not None else None
        if room is not None and len(statements) > room:
            return self._answer(client, Rejected(
                comm_id=comm_id, seq=unit.seq, reason=RejectReason.BUFFER_FULL,
                detail=f"the robot's buffer has room for {room} statement(s); this communication has {len(statements)}",
            ))
        numbers = tuple(range(self.next_number, self.next_number + len(statements)))
        self.next_number += len(statements)
        step = self._answer(client, Accepted(comm_id=comm_id, numbers=numbers))
        step.accepted = list(zip(numbers, statements))
        if self._client is not None:
            self.senders.update(dict.fromkeys(numbers, self._client))
        step.replies += [self.report(n, StatementState.RECEIVED) for n in numbers]
        return step

    def _answer(self, client: _ClientState, answer: Answer) -> ReceiverStep:
        """Close the open communication with ``answer`` (stored for re-delivery)."""
        assert answer.comm_id == client.last_answered + 1
        client.last_answered = answer.comm_id
        client.units = []
        client.answers[answer.comm_id] = answer
        while len(client.answers) > KEPT_ANSWERS:
            client.answers.popitem(last=False)
        if isinstance(answer, Rejected):
            log.info("communication %d rejected: %s (%s)", answer.comm_id, answer.reason.value, answer.detail)
        return ReceiverStep(replies=[answer])

    # -- recovery and status -------------------------------------------------------------------

    def _recovery(self, cmd: Recovery) -> ReceiverStep:
        if isinstance(cmd, Stop):
            return self._stop(cmd)
        if self._client is None:
            return ReceiverStep(replies=[Rejected(reason=RejectReason.NO_SESSION, detail="send hello before commands", final=False)])
        client = self._clients[self._client]
        if cmd.command_id <= client.last_applied_command:
            ack = client.acks.get(cmd.command_id)
            return ReceiverStep(replies=[ack] if ack is not None else [])
        if cmd.command_id > client.last_applied_command + 1:
            return ReceiverStep(replies=[RecoveryAck(
                command_id=cmd.command_id, applied=False,
                detail=f"{cmd.type} command {cmd.command_id} jumps ahead: the next command id is "
                f"{client.last_applied_command + 1}; nothing done",
            )])
        self._advance(client, cmd.command_id)
        return ReceiverStep(recoveries=[cmd])

    def _stop(self, cmd: Stop) -> ReceiverStep:
        """A stop is never locked out: applied whatever its id, before hello too."""
        if self._client is None:
            return ReceiverStep(recoveries=[cmd])
        client = self._clients[self._client]
        if cmd.command_id in client.stops:
            ack = client.acks.get(cmd.command_id)
            return ReceiverStep(replies=[ack] if ack is not None else [])
        client.stops[cmd.command_id] = None
        while len(client.stops) > KEPT_ANSWERS:
            client.stops.popitem(last=False)
        if cmd.command_id == client.last_applied_command + 1:
            self._advance(client, cmd.command_id)
        return ReceiverStep(recoveries=[cmd])

    @staticmethod
    def _advance(client: _ClientState, command_id: int) -> None:
        """``command_id`` is applied; so are the stops already applied right after it."""
        client.last_applied_command = command_id
        while client.last_applied_command + 1 in client.stops:
            client.last_applied_command += 1

    def ack(self, cmd: Recovery, applied: bool, detail: str = "", robot: RobotSnapshot | None = None) -> RecoveryAck:
        """Record and return the acknowledgement of a recovery command the robot has handled."""
        ack = RecoveryAck(command_id=cmd.command_id, applied=applied, detail=detail, robot=robot)
        if self._client is not None:
            acks = self._clients[self._client].acks
            acks[cmd.command_id] = ack
            while len(acks) > KEPT_ANSWERS:
                acks.popitem(last=False)
        return ack

    def report(
        self, number: int, state: StatementState, reason: str | None = None, robot: RobotSnapshot | None = None,
        robot_time: float | None = None,
    ) -> StatusReport:
        """Log the next status report (kept for replay) and return it for sending; ``robot_time`` is
        the robot's clock at the change (s)."""
        rep = StatusReport(report_seq=len(self.reports) + 1, number=number, state=state, reason=reason, robot=robot,
                           robot_time=robot_time)
        self.reports.append(rep)
        return rep


class CommandSender:
    """The console's end of the command channel: numbering, keeping and re-sending units.

    A welcome from another robot session (the robot restarted) ends the old session here: what
    it left unanswered is returned by ``begin_session`` as a ``SessionRestart`` and dropped, never
    sent to the new robot (it may have run on the old one), and numbering starts again at 1.
    """

    def __init__(self, client_id: str, per_unit: int = 100, kept_identity: bool = False) -> None:
        self.client_id = client_id
        self.per_unit = per_unit
        self.kept_identity = kept_identity
        """This process kept ``client_id`` from an earlier one (``server.up.identity``): until its
        first welcome its hello says ``new_process`` and its caller sends nothing (no unit, no
        command) but the hello; at that welcome its counters go on from the robot's (``adopt``)."""
        self.session_id: str | None = None
        self._fresh()

    def _fresh(self) -> None:
        """Counters and books of a new robot session."""
        self.next_comm = 1
        self.next_command = 1
        self.outbox: OrderedDict[int, list[bytes]] = OrderedDict()  # unanswered communications
        self.answers: dict[int, Answer] = {}
        self.statuses: dict[int, list[StatementState]] = {}
        self.last_report_seq = 0
        self._unacked: OrderedDict[int, Recovery] = OrderedDict()
        self._refusals: set[str] = set()
        self.first_comm = 1  # below: an earlier process's under this identity (``adopt``)
        self.first_command = 1
        self.renumbered: Renumbered | None = None

    @property
    def last_answered_comm(self) -> int:
        # answers come in communication order, so the unanswered ones are always the newest
        return min(self.outbox) - 1 if self.outbox else self.next_comm - 1

    def submit(self, statements: list[Statement]) -> tuple[int, list[bytes]]:
        """Open a communication with these statements; returns its number and the units to send."""
        comm_id = self.next_comm
        self.next_comm += 1
        units = split_into_units(comm_id, statements, self.per_unit)
        self.outbox[comm_id] = units
        return comm_id, units

    def command(self, kind: type[Recovery], **fields: object) -> Recovery:
        """A new recovery command (kept until acknowledged)."""
        cmd = kind(command_id=self.next_command, **fields)
        self.next_command += 1
        self._unacked[cmd.command_id] = cmd
        return cmd

    def unacked(self, command_id: int) -> Recovery | None:
        """The recovery command of that id still waiting for its acknowledgement, if any."""
        return self._unacked.get(command_id)

    def hello(self) -> Hello:
        return Hello(
            client_id=self.client_id,
            session_id=self.session_id,
            last_answered_comm=self.last_answered_comm,
            last_report_seq=self.last_report_seq,
            last_acked_command=min(self._unacked) - 1 if self._unacked else self.next_command - 1,
            new_process=self.kept_identity and self.session_id is None,
        )

    def begin_session(self, welcome: Welcome) -> SessionRestart | None:
        """Take the welcome's session; on a new one (the robot restarted), drop the old
        session's books and return what it left unknown (None when the session is the same).
        With ``kept_identity``, the first welcome may come from a robot that knows the identity (a
        console that started again and kept it): the counters go on from the robot's (``adopt``)."""
        old = self.session_id
        self.session_id = welcome.session_id
        if old is None:
            if self.kept_identity:
                self.adopt(welcome)
            return None
        if old == welcome.session_id:
            return None
        numbered = set(self.statuses) | {n for a in self.answers.values() if isinstance(a, Accepted) for n in a.numbers}
        restart = SessionRestart(
            old_session=old, new_session=welcome.session_id, comms=tuple(self.outbox), commands=tuple(self._unacked),
            numbers=tuple(sorted(n for n in numbered if self.final_state(n) is None)),
        )
        log.warning("%s", restart.describe())
        self._fresh()
        return restart

    def adopt(self, welcome: Welcome) -> None:
        """Go on from the counters a robot kept for this identity (an earlier process under the
        same client id): what this sender numbered before its first welcome (nothing was sent yet)
        is numbered again after the robot's last answered communication and applied command, and
        ``renumbered`` says old -> new for the caller's books. Answers and acknowledgements the
        robot replays for the earlier process are not this sender's (``on_message`` skips them)."""
        comm_base, command_base = welcome.last_answered_comm, welcome.last_applied_command
        self.first_comm, self.first_command = comm_base + 1, command_base + 1
        if comm_base == 0 and command_base == 0:
            return
        comms = {old: comm_base + i for i, old in enumerate(self.outbox, start=1)}
        commands = {old: command_base + i for i, old in enumerate(self._unacked, start=1)}
        self.outbox = OrderedDict(
            (comms[old], split_into_units(comms[old], [s for u in units for s in decode_unit(u).statements], self.per_unit))
            for old, units in self.outbox.items()
        )
        self._unacked = OrderedDict((commands[old], cmd.model_copy(update={"command_id": commands[old]}))
                                    for old, cmd in self._unacked.items())
        self.next_comm = comm_base + len(comms) + 1
        self.next_command = command_base + len(commands) + 1
        self.renumbered = Renumbered(comms=comms, commands=commands)
        log.info("robot session %s knows this identity: communications go on from %d, commands from %d",
                 welcome.session_id, self.first_comm, self.first_command)

    def on_welcome(self, welcome: Welcome) -> list[bytes | Recovery]:
        """What to send again after ``welcome``: units the robot lacks, then unapplied commands."""
        self.begin_session(welcome)
        out: list[bytes | Recovery] = []
        for comm_id, units in self.outbox.items():
            if comm_id <= welcome.last_answered_comm:
                continue  # its answer is being replayed
            held = welcome.units_held if comm_id == welcome.last_answered_comm + 1 else 0
            out += units[held:]
        out += [c for i, c in self._unacked.items() if i > welcome.last_applied_command]
        return out

    def on_message(self, msg: BaseModel) -> None:
        """Record an answer, a status report or an acknowledgement (repeats are ignored)."""
        if isinstance(msg, Rejected) and not msg.final:
            key = f"{msg.reason.value}: {msg.detail}"
            if key not in self._refusals:  # the same refusal again is not news
                self._refusals.add(key)
                log.warning("robot refused a unit or message: %s (%s)", msg.reason.value, msg.detail)
        elif isinstance(msg, (Accepted, Rejected)) and msg.comm_id is not None:
            if msg.comm_id < self.first_comm:
                return  # an answer to an earlier process under this identity (a replay)
            if msg.comm_id not in self.answers:
                self.answers[msg.comm_id] = msg
            self.outbox.pop(msg.comm_id, None)
        elif isinstance(msg, StatusReport):
            if msg.report_seq <= self.last_report_seq:
                return
            self.last_report_seq = msg.report_seq
            self.statuses.setdefault(msg.number, []).append(msg.state)
        elif isinstance(msg, RecoveryAck):
            if msg.command_id >= self.first_command:  # not an earlier process's (a replay)
                self._unacked.pop(msg.command_id, None)

    def final_state(self, number: int) -> StatementState | None:
        finals = [s for s in self.statuses.get(number, []) if s in FINAL_STATES]
        return finals[-1] if finals else None

    @property
    def idle(self) -> bool:
        """No communication waits for its answer and no command for its acknowledgement."""
        return not self.outbox and not self._unacked


@dataclass(frozen=True)
class Renumbered:
    """What ``CommandSender.adopt`` numbered again: old -> new communication and command ids."""

    comms: dict[int, int]
    commands: dict[int, int]


@dataclass(frozen=True)
class SessionRestart:
    """What a new robot session (the robot process restarted) left without an answer: the
    communications and recovery commands of the old session that were not answered, and the
    numbered statements without a final status. Their fate is unknown: they may have run."""

    old_session: str
    new_session: str
    comms: tuple[int, ...]
    commands: tuple[int, ...]
    numbers: tuple[int, ...]

    def describe(self) -> str:
        parts = []
        if self.numbers:
            parts.append("statements " + _ranges(self.numbers))
        if self.comms:
            parts.append("unanswered communications " + _ranges(self.comms))
        if self.commands:
            parts.append("unacknowledged commands " + _ranges(self.commands))
        what = "; ".join(parts) or "nothing"
        return f"robot restarted (session {self.old_session} -> {self.new_session}): the fate of {what} is unknown"


def _ranges(numbers: tuple[int, ...]) -> str:
    """``1-4, 7`` for (1, 2, 3, 4, 7)."""
    out: list[list[int]] = []
    for n in sorted(numbers):
        if out and out[-1][1] == n - 1:
            out[-1][1] = n
        else:
            out.append([n, n])
    return ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in out)
