"""Every JSON message of the command channel, one typed definition each.

The command channel (thesis §4.4) carries two kinds of WebSocket messages:

* **binary** messages are *command units* (``shared.wire.units``): a fixed header and a JSON body
  of statements;
* **text** messages are the JSON documents defined here, each an object with a ``"type"``.

Console -> robot: ``hello``, ``stop``, ``resume``, ``skip``, ``abort``, ``heartbeat`` (and binary
units). Robot -> console: ``welcome``, ``accepted``, ``rejected``, ``status``, ``recovery_ack``,
``heartbeat``, ``halted``. Each end refuses the types only the other sends.

Numbers are finite (no NaN or infinity in any field) and JSON is strict (no repeated keys):
``shared.wire.strict_json``. Liveness (heartbeats, the silence limit): ``shared.wire.liveness``.

Delivery guarantees and the exactly-once reasoning
==================================================

The link may cut the connection at any moment (a fault, a restarted relay); whatever was in flight
is lost, in either direction. The protocol makes every statement run at most once and end in
exactly one final status, with these idempotency keys:

``(client_id, comm_id)``
    A *communication* is identified by the client's id (chosen once per console session, sent in
    ``hello``) and a communication number that the client increases by one per communication,
    starting at 1. A unit is identified by ``(client_id, comm_id, seq)`` with ``seq`` counting from
    0 inside the communication.
``(client_id, command_id)``
    Each recovery command carries a client-chosen number, increasing per client.
``report_seq``
    Every status report the robot emits gets the next number of one robot-wide sequence.

Why nothing runs twice: statements enter the robot's buffer only when the unit that ends their
communication arrives, and in the same step the receiver records the communication's answer under
its key. A re-delivered unit of an answered communication (``comm_id`` not above the last answered
one for that client) is not processed again; the receiver sends the stored answer again instead,
with the same statement numbers. Units of the communication in progress are taken only in order
(``seq`` equal to the next expected one); a repeat of an already held unit is ignored. Recovery
commands already seen (``command_id`` not above the last applied one) are acknowledged again
without being applied again, so a repeated ``skip`` never skips a second statement, and a ``skip``
names the statement it means, so a late one cannot skip the wrong statement.

Why nothing vanishes: the client keeps every unit of a communication until it has that
communication's answer, and every recovery command until it is acknowledged. After a reconnect it
sends ``hello`` with the last communication it has an answer for and the last status report it
has seen; the robot answers ``welcome`` with the last communication it has answered for that client
and how many units it holds of the next one, then sends again every answer and every status report
the client has not seen. The client then sends the units the robot does not hold (and its
unacknowledged recovery commands); it sends nothing else between ``hello`` and ``welcome``, since
until then it cannot know which unit the robot expects. A unit of a later communication that
arrives anyway is refused with a *non-final* rejection (``final`` false), which closes nothing;
a gap inside the open communication (unit 3 while unit 2 is expected) is a client error and ends
that communication as rejected.

The robot must send its replies on a connection in the order its receiver produced them (one
writer per connection): the client drops any status report whose ``report_seq`` it has passed. At-least-once delivery plus the keys above gives exactly-once
effect.

Why every statement ends once: the robot gives each accepted statement one final status (done,
failed, skipped or aborted) and logs it under its ``report_seq``; replays after a reconnect repeat
the same reports with the same ``report_seq``, which the client deduplicates.

Limits: the robot keeps answers and reports in memory; a robot process restart begins a new
``session_id`` (in ``welcome``), and the client must then treat statements without a final status
as unknown. That is the one case the keys cannot cover.
"""

from __future__ import annotations

from enum import Enum, IntEnum
from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, model_validator

from shared.language.statements import Statement
from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S, HEARTBEAT_INTERVAL_S
from shared.wire.strict_json import StrictJSONError, loads_strict

PROTOCOL_VERSION = 1
MAX_MESSAGE_BYTES = 1 << 20
"""Largest JSON text message the robot accepts (1 MiB); an answer listing 10,000 numbers is about 60 kB."""
MAX_ROBOT_MESSAGE_BYTES = 4 << 20
"""Largest JSON text message a console accepts from its robot (4 MiB: a welcome's account of a full
buffer); the robot keeps its welcome under ``WELCOME_BUDGET_BYTES``."""
WELCOME_BUDGET_BYTES = 3 << 20
"""What a welcome's account (``holds`` then ``ran``) may take; past it the lists are cut (``holds_total`` says how many are held)."""

Vec3 = tuple[float, float, float]
Vec6 = tuple[float, float, float, float, float, float]


MAX_TEXT = 2000
"""Longest free text (a reason, a detail) a message may carry."""
Name = Annotated[str, Field(min_length=1, max_length=64)]


class _Model(BaseModel):
    # no NaN or infinity in any float of any message: one number must never reach the servo
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class RobotState(IntEnum):
    """What the robot is doing; the same codes travel in telemetry frames (one byte)."""

    IDLE = 0  # buffer empty, holding position
    RUNNING = 1  # executing a statement
    STOPPED = 2  # stopped by the operator (or by silence on the link); waits for resume, skip or abort
    FAULT = 3  # stopped on something unexpected; waits for recovery
    DISCONNECTED = 4  # no console connected: nothing new starts; past the silence limit the arm stops itself


class ControlMode(IntEnum):
    """The arm's control mode, as ``MODE POSITION`` / ``MODE FORCE`` statements set it (one byte
    in telemetry). The console's jog mode, joint or tool, is ``shared.program.generator.JogMode``."""

    POSITION = 0
    FORCE = 1


class ObjectPose(_Model):
    """Where the robot perceives a movable object (its sensing of the cell, e.g. a camera): the
    object's frame in the robot's base frame (m; fixed-axis XYZ roll-pitch-yaw, rad)."""

    name: str = Field(min_length=1, max_length=64)
    base_p: Vec3
    base_rpy: Vec3


class RobotSnapshot(_Model):
    """The robot's state at one instant, as reported with a final status.

    ``q`` has the robot's own number of joints (rad); the tool pose is in the base frame (m, and
    fixed-axis XYZ roll-pitch-yaw in rad); ``wrench`` is force (N) then torque (N m) at the tool.
    ``held`` names the object in the gripper; ``objects`` are the movable objects where the robot
    perceives them (``None``: the robot does not report objects; the console then infers them from
    the grasps and releases it ran).
    """

    state: RobotState
    mode: ControlMode = ControlMode.POSITION
    q: tuple[float, ...] = Field(min_length=1, max_length=6)
    base_p_tool: Vec3
    tool_rpy: Vec3
    gripper: float = Field(0.0, description="gripper opening (m)")
    wrench: Vec6 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    held: str | None = Field(None, max_length=64)
    objects: tuple[ObjectPose, ...] | None = Field(None, max_length=256)


# ---------------------------------------------------------------------------------------------
# Handshake


class Hello(_Model):
    """First message of the console on every (re)connection."""

    type: Literal["hello"] = "hello"
    protocol: int = PROTOCOL_VERSION
    client_id: str = Field(min_length=1, max_length=64)
    session_id: str | None = Field(
        None, min_length=1, max_length=64,
        description="the robot session the counters below belong to (None: a client that never had a welcome); "
        "a robot with another session treats them as 0",
    )
    last_answered_comm: int = Field(0, ge=0, description="newest communication the client has an answer for")
    last_report_seq: int = Field(0, ge=0, description="newest status report the client has seen")
    last_acked_command: int = Field(0, ge=0, description="newest recovery command acknowledged")
    new_process: bool = Field(
        False, description="a console process that kept its identity from an earlier one and has sent nothing "
        "under it yet: the robot drops that identity's half-sent communication, and the client goes on from the "
        "welcome's counters",
    )


MAX_HELD_LISTED = 5000
"""Statements a welcome lists at most as held (the robot's buffer holds 5,000 by default)."""
MAX_RAN_LISTED = 1000
"""Finished statements a welcome lists at most (the newest)."""
MAX_HELD_TEXT = 200


class HeldStatement(_Model):
    """A statement the robot holds (running now, or queued behind it) or has finished, as a
    welcome accounts for it: a console that starts again shows it before anybody resumes."""

    number: int = Field(ge=1, description="the robot's number of the statement")
    text: str = Field(max_length=MAX_HELD_TEXT, description="the statement in the language (cut at 200 characters)")
    running: bool = Field(False, description="the statement the robot is executing (or was, when it stopped)")
    client_id: str | None = Field(None, max_length=64, description="the client that sent it")
    state: Literal["received", "running", "done", "failed", "skipped", "aborted"] = Field(
        "received", description="its status now: received (queued), running, or the final one it reached",
    )
    statement: Statement | None = Field(None, description="the statement itself (for the console's sent list)")


class Welcome(_Model):
    """The robot's reply to ``hello``; followed by replays of missed answers and reports."""

    type: Literal["welcome"] = "welcome"
    protocol: int = PROTOCOL_VERSION
    session_id: str = Field(min_length=1, max_length=64, description="changes when the robot restarts")
    last_answered_comm: int = Field(ge=0, description="newest communication of this client the robot answered")
    units_held: int = Field(ge=0, description="units of communication last_answered_comm + 1 already held")
    last_applied_command: int = Field(ge=0, description="newest recovery command of this client applied")
    last_report_seq: int = Field(ge=0, description="newest status report the robot has emitted")
    heartbeat_s: float = Field(HEARTBEAT_INTERVAL_S, gt=0.0, le=60.0, description="interval of the robot's heartbeats")
    silence_limit_s: float = Field(
        DEFAULT_SILENCE_LIMIT_S, gt=0.0, le=3600.0, description="silence beyond the expected arrival at which the robot stops"
    )
    halted: str | None = Field(None, max_length=MAX_TEXT, description="why the robot holds by itself now, if it does")
    held_s: float = Field(
        0.0, ge=0.0, le=3600.0,
        description="how long the hello waited at the robot for its core to be built: not part of the round trip",
    )
    holds: list[HeldStatement] = Field(
        default_factory=list, max_length=MAX_HELD_LISTED,
        description="what the robot holds now, running first, then queued in order (a restarted console shows them)",
    )
    holds_total: int = Field(0, ge=0, description="how many statements it holds (more than listed when the list is cut)")
    ran: list[HeldStatement] = Field(
        default_factory=list, max_length=MAX_RAN_LISTED,
        description="the newest statements that reached a final status, oldest first (what a restarted console shows as run)",
    )
    numbered: int = Field(0, ge=0, description="the highest number the robot has given a statement (0: none yet)")


class Heartbeat(_Model):
    """Sent every ``heartbeat_s`` by each end of the command channel (``shared.wire.liveness``):
    its arrival is what tells the other end the line and its sender are alive."""

    type: Literal["heartbeat"] = "heartbeat"
    seq: int = Field(ge=0, description="counts the sender's heartbeats on this connection")


class HaltCause(str, Enum):
    """Why the robot stopped by itself (not on a statement's failure, not on the operator's stop)."""

    SILENCE = "silence"  # nothing heard from the console past the silence limit
    INTERNAL_ERROR = "internal_error"  # the executor's last-resort boundary caught an error
    SENSOR_FAULT = "sensor_fault"  # a sensor the robot moves by (the wrist force sensor) reads invalid
    FOLLOWING_ERROR = "following_error"  # the arm is not where its joint servo holds it (a joint drags)
    OBJECT_LOST = "object_lost"  # the held object left the fingers while no statement ran


class Halted(_Model):
    """The robot made a controlled stop by itself and holds its queue until the operator's
    ``resume``, ``skip`` or ``abort``; ``detail`` says why in words."""

    type: Literal["halted"] = "halted"
    cause: HaltCause
    detail: str = Field(max_length=MAX_TEXT)
    robot: RobotSnapshot | None = None


# ---------------------------------------------------------------------------------------------
# Answers to a communication


class RejectReason(str, Enum):
    """Why a unit, a message or a whole communication was refused."""

    BAD_HEADER = "bad_header"  # too short, wrong magic or version, unknown flags
    LENGTH_MISMATCH = "length_mismatch"  # header's body length differs from the bytes received
    TOO_LARGE = "too_large"  # body length over the limit
    BAD_JSON = "bad_json"  # body is not UTF-8 JSON
    BAD_BODY = "bad_body"  # JSON but not a list of statement objects
    UNKNOWN_KIND = "unknown_kind"  # a statement with a kind the language does not have
    INVALID_STATEMENT = "invalid_statement"  # a known kind with bad fields
    OUT_OF_SEQUENCE = "out_of_sequence"  # a unit whose seq or comm_id is not the expected one
    NO_SESSION = "no_session"  # a unit or command before ``hello``
    BAD_MESSAGE = "bad_message"  # a text message that is not one of the types here
    BUFFER_FULL = "buffer_full"  # the robot cannot hold more statements now
    PROTOCOL = "protocol"  # hello with a protocol version this robot does not speak


class Accepted(_Model):
    """The communication was taken whole; ``numbers[i]`` is the number of its i-th statement."""

    type: Literal["accepted"] = "accepted"
    comm_id: int = Field(ge=1)
    numbers: tuple[int, ...]


class Rejected(_Model):
    """The communication (or a unit or message that could not be tied to one) was refused.

    Nothing of a rejected communication runs. ``statement_index`` counts statements from 0 across
    the whole communication; ``statement`` is the offending JSON text, cut to 200 characters.
    """

    type: Literal["rejected"] = "rejected"
    comm_id: int | None = Field(None, ge=1, description="None when the unit header was unreadable")
    seq: int | None = Field(None, ge=0)
    reason: RejectReason
    detail: str = Field(max_length=MAX_TEXT)
    statement_index: int | None = Field(None, ge=0)
    statement: str | None = Field(None, max_length=400)
    final: bool = Field(
        True,
        description="True: the answer of communication comm_id (it will never run). False: only this "
        "unit or message was refused (out of sequence, before hello, unreadable) and the communication "
        "stays open",
    )


# ---------------------------------------------------------------------------------------------
# Status of each statement


class StatementState(str, Enum):
    RECEIVED = "received"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"
    SKIPPED = "skipped"  # skipped by the operator's ``skip``
    ABORTED = "aborted"  # flushed from the buffer by ``abort``

    @property
    def final(self) -> bool:
        return self in _FINAL_STATES


_FINAL_STATES = frozenset({StatementState.DONE, StatementState.FAILED, StatementState.SKIPPED, StatementState.ABORTED})
FINAL_STATES = _FINAL_STATES


class StatusReport(_Model):
    """One step in the life of statement ``number``.

    ``done`` carries the robot's state at the end; ``failed`` carries the reason and the state.
    """

    type: Literal["status"] = "status"
    report_seq: int = Field(ge=1)
    number: int = Field(ge=1)
    state: StatementState
    reason: str | None = Field(None, max_length=MAX_TEXT)
    robot: RobotSnapshot | None = None
    robot_time: float | None = Field(
        None, ge=0.0, description="the robot's own clock (s since it started) when the statement reached this state",
    )

    @model_validator(mode="after")
    def _complete(self) -> "StatusReport":
        if self.state in (StatementState.DONE, StatementState.FAILED) and self.robot is None:
            raise ValueError(f"a {self.state.value} report carries the robot state")
        if self.state is StatementState.FAILED and not self.reason:
            raise ValueError("a failed report carries the reason")
        return self


# ---------------------------------------------------------------------------------------------
# Recovery commands (console -> robot)


class _Recovery(_Model):
    command_id: int = Field(ge=1, description="increases by one per recovery command of a client")


class Stop(_Recovery):
    """Stop now. A priority message: the robot acts on it before any buffered statement."""

    type: Literal["stop"] = "stop"
    priority: Literal[True] = True


class Resume(_Recovery):
    """Continue with the current statement (after ``stop`` or a fault)."""

    type: Literal["resume"] = "resume"


class SkipCurrent(_Recovery):
    """End the current statement as ``skipped`` and go on with the next one.

    ``number`` names the statement meant; if another one is current when this arrives, nothing is
    skipped and the acknowledgement says so.
    """

    type: Literal["skip"] = "skip"
    number: int = Field(ge=1)


class AbortFlush(_Recovery):
    """Stop, end the current and every buffered statement as ``aborted``, and go idle."""

    type: Literal["abort"] = "abort"


class RecoveryAck(_Model):
    """The robot's answer to a recovery command; ``applied`` is False for a repeat or a no-op."""

    type: Literal["recovery_ack"] = "recovery_ack"
    command_id: int = Field(ge=1)
    applied: bool
    detail: str = Field("", max_length=MAX_TEXT)
    robot: RobotSnapshot | None = None


RECOVERY_TYPES = frozenset({"stop", "resume", "skip", "abort"})
CLIENT_TYPES = frozenset({"hello", "heartbeat"}) | RECOVERY_TYPES
"""Message types a console may send; the robot refuses any other (a client-sent ``rejected`` is
not the robot's own error)."""
ROBOT_TYPES = frozenset({"welcome", "accepted", "rejected", "status", "recovery_ack", "heartbeat", "halted"})
"""Message types the robot sends; the console ignores any other."""

Message = Annotated[
    Union[
        Hello, Welcome, Accepted, Rejected, StatusReport, Stop, Resume, SkipCurrent, AbortFlush, RecoveryAck,
        Heartbeat, Halted,
    ],
    Field(discriminator="type"),
]
Answer = Union[Accepted, Rejected]
Recovery = Union[Stop, Resume, SkipCurrent, AbortFlush]

message_adapter: TypeAdapter[Message] = TypeAdapter(Message)


def encode_message(message: BaseModel) -> str:
    """The JSON text of one message (SI values, no ``None`` fields)."""
    return message.model_dump_json(exclude_none=True)


def decode_message(data: str | bytes, allowed: frozenset[str] | None = None,
                   max_bytes: int = MAX_MESSAGE_BYTES) -> Message | Rejected:
    """Parse one text message; anything malformed becomes a ``Rejected`` (never an exception).

    The JSON must be strict (``shared.wire.strict_json``: no NaN, no repeated key). ``allowed``
    names the types this end takes from the other (``CLIENT_TYPES`` on the robot); any other
    type is refused as ``bad_message``.
    """
    if len(data) > max_bytes:
        return Rejected(reason=RejectReason.TOO_LARGE, detail=f"message of {len(data)} bytes; limit {max_bytes}")
    try:
        obj = loads_strict(data)
    except StrictJSONError as exc:
        return Rejected(reason=RejectReason.BAD_JSON, detail=f"message is not strict JSON: {_one_line(exc)}")
    if not isinstance(obj, dict):
        return Rejected(reason=RejectReason.BAD_MESSAGE, detail="message is not a JSON object")
    kind = obj.get("type")
    if allowed is not None and kind not in allowed:
        return Rejected(
            reason=RejectReason.BAD_MESSAGE,
            detail=f"message type {str(kind)[:64]!r} is not taken here; valid: {', '.join(sorted(allowed))}",
        )
    try:
        return message_adapter.validate_python(obj)
    except ValidationError as exc:
        return Rejected(reason=RejectReason.BAD_MESSAGE, detail=f"message type {str(kind)[:64]!r}: {_first_error(exc)}")


def _one_line(exc: BaseException) -> str:
    return str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__


def _first_error(exc: ValidationError) -> str:
    err = exc.errors()[0]
    where = ".".join(str(p) for p in err.get("loc", ())) or "(root)"
    return f"{where}: {err.get('msg', 'invalid')}"[:300]
