"""The robot's end of the command channel (``CommandReceiver``) under the safety contract of
issue 14: stop is never locked out, other recovery ids cannot jump ahead, the protocol version is
checked, only client message types are taken, counters of an earlier robot session read as 0,
and a communication that would overflow the robot's buffer is refused whole."""

from __future__ import annotations

from shared.language.statements import Event
from shared.wire.messages import (
    PROTOCOL_VERSION,
    AbortFlush,
    Heartbeat,
    Hello,
    RecoveryAck,
    Rejected,
    RejectReason,
    Resume,
    SkipCurrent,
    StatementState,
    Stop,
    Welcome,
    encode_message,
)
from shared.wire.session import CommandReceiver
from shared.wire.units import encode_unit


def greeted(**kw) -> CommandReceiver:
    receiver = CommandReceiver("robot-1", **kw)
    (welcome,) = receiver.on_text(encode_message(Hello(client_id="c"))).replies
    assert isinstance(welcome, Welcome)
    return receiver


def apply(receiver: CommandReceiver, cmd) -> tuple[list, list]:
    """Feed one command; acknowledge what is passed on (as the robot would)."""
    step = receiver.on_text(encode_message(cmd))
    acks = [receiver.ack(c, True, "done") for c in step.recoveries]
    return step.recoveries, step.replies + acks


# -- recovery command ids ---------------------------------------------------------------------------


def test_a_stop_far_ahead_does_not_lock_out_later_stops() -> None:
    receiver = greeted()
    passed, _ = apply(receiver, Stop(command_id=1000))
    assert passed == [Stop(command_id=1000)]
    passed, _ = apply(receiver, Stop(command_id=2))  # finding 6: this one was ignored
    assert passed == [Stop(command_id=2)]
    welcome = receiver.on_text(encode_message(Hello(client_id="c", session_id="robot-1"))).replies[0]
    assert welcome.last_applied_command == 0  # neither was the next id


def test_a_repeated_stop_is_acknowledged_again_not_applied_again() -> None:
    receiver = greeted()
    passed, replies = apply(receiver, Stop(command_id=7))
    assert passed and isinstance(replies[-1], RecoveryAck)
    passed, replies = apply(receiver, Stop(command_id=7))
    assert passed == [] and replies == [RecoveryAck(command_id=7, applied=True, detail="done")]


def test_a_stop_before_hello_is_applied() -> None:
    receiver = CommandReceiver("robot-1")
    step = receiver.on_text(encode_message(Stop(command_id=5)))
    assert step.recoveries == [Stop(command_id=5)]
    # other commands still need the hello
    (rej,) = receiver.on_text(encode_message(Resume(command_id=1))).replies
    assert rej.reason is RejectReason.NO_SESSION


def test_resume_skip_abort_must_carry_the_next_id() -> None:
    receiver = greeted()
    assert apply(receiver, Stop(command_id=1))[0]
    passed, (ack,) = apply(receiver, Resume(command_id=5))
    assert passed == [] and ack.applied is False and "jumps ahead" in ack.detail and "next command id is 2" in ack.detail
    passed, (ack,) = apply(receiver, AbortFlush(command_id=3))
    assert passed == [] and not ack.applied
    assert apply(receiver, SkipCurrent(command_id=2, number=1))[0]
    assert apply(receiver, Resume(command_id=3))[0]
    passed, replies = apply(receiver, Resume(command_id=3))  # a repeat: acknowledged again
    assert passed == [] and replies[0].applied


def test_a_stop_out_of_turn_is_counted_when_the_gap_before_it_fills() -> None:
    receiver = greeted()
    assert apply(receiver, Stop(command_id=2))[0]  # arrives before command 1 (a resend order)
    assert apply(receiver, Resume(command_id=1))[0]
    assert apply(receiver, AbortFlush(command_id=3))[0]  # 2 is applied, so 3 is the next one


# -- protocol and message types -----------------------------------------------------------------------


def test_a_hello_of_another_protocol_is_refused_and_greets_nobody() -> None:
    receiver = CommandReceiver("robot-1")
    (rej,) = receiver.on_text(encode_message(Hello(client_id="c", protocol=PROTOCOL_VERSION + 1))).replies
    assert rej.reason is RejectReason.PROTOCOL and rej.final is False
    assert rej.detail == f"protocol {PROTOCOL_VERSION + 1} not supported; this robot speaks {PROTOCOL_VERSION}"
    assert not receiver.greeted
    (rej,) = receiver.on_unit(encode_unit(1, 0, [Event(name="x")], True)).replies
    assert rej.reason is RejectReason.NO_SESSION


def test_robot_message_types_from_a_client_are_refused_not_echoed() -> None:
    receiver = greeted()
    sent = Rejected(comm_id=1, reason=RejectReason.BUFFER_FULL, detail="a client pretending to be the robot")
    (rej,) = receiver.on_text(encode_message(sent)).replies
    assert rej.reason is RejectReason.BAD_MESSAGE and rej.final is False and "'rejected'" in rej.detail
    assert "pretending" not in rej.detail
    for text in ('{"type":"status","report_seq":1,"number":1,"state":"done"}', '{"type":"halted"}', '{"type":"welcome"}'):
        (rej,) = receiver.on_text(text).replies
        assert rej.reason is RejectReason.BAD_MESSAGE


def test_a_repeated_key_cannot_turn_a_hello_into_a_stop() -> None:
    receiver = greeted()
    step = receiver.on_text('{"type":"hello","type":"stop","command_id":1,"client_id":"c"}')
    assert step.recoveries == [] and step.replies[0].reason is RejectReason.BAD_JSON


def test_a_heartbeat_is_taken_silently() -> None:
    receiver = greeted()
    step = receiver.on_text(encode_message(Heartbeat(seq=3)))
    assert step.replies == [] and step.recoveries == [] and step.accepted == []


# -- robot restarts -------------------------------------------------------------------------------------


def test_counters_of_an_earlier_robot_session_read_as_zero() -> None:
    receiver = greeted()
    receiver.on_unit(encode_unit(1, 0, [Event(name="a"), Event(name="b")], True))
    reports = len(receiver.reports)
    hello = Hello(client_id="c", session_id="robot-0", last_answered_comm=40, last_report_seq=900, last_acked_command=9)
    replies = receiver.on_text(encode_message(hello)).replies
    assert isinstance(replies[0], Welcome) and replies[0].session_id == "robot-1"
    assert [r.type for r in replies[1:]] == ["accepted"] + ["status"] * reports  # everything of this session
    # the same counters with this session's id are taken as they are
    same = hello.model_copy(update={"session_id": "robot-1", "last_answered_comm": 1, "last_report_seq": reports})
    assert receiver.on_text(encode_message(same)).replies[1:] == []


# -- the robot's buffer -----------------------------------------------------------------------------------


def test_a_communication_over_the_room_left_is_refused_as_buffer_full() -> None:
    room = [3]
    receiver = greeted(room=lambda: room[0])
    step = receiver.on_unit(encode_unit(1, 0, [Event(name="e")] * 4, True))
    (rej,) = step.replies
    assert rej.reason is RejectReason.BUFFER_FULL and rej.final and rej.comm_id == 1 and step.accepted == []
    assert "room for 3" in rej.detail
    step = receiver.on_unit(encode_unit(2, 0, [Event(name="e")] * 3, True))
    assert [n for n, _ in step.accepted] == [1, 2, 3]
    assert [r.state for r in step.replies[1:]] == [StatementState.RECEIVED] * 3


def test_a_new_process_under_a_kept_identity_starts_clean_past_the_robots_counters() -> None:
    """The dead process left a half-sent communication and a stop applied out of turn (id 3 while
    2 never came): the new process's hello drops both, so its own command 3, a stop, is applied
    rather than acknowledged as a repeat, and its first communication is not spliced onto old units."""
    from shared.language.statements import Event
    from shared.wire.messages import Hello, Stop, encode_message

    r = CommandReceiver("s")
    r.on_text(encode_message(Hello(client_id="c")))
    r.on_text(encode_message(Stop(command_id=1)))
    r.on_text(encode_message(Stop(command_id=3)))  # applied (a stop always is), out of turn
    r.on_unit(encode_unit(1, 0, [Event(name="half")], False))  # never finished
    r.disconnect()
    welcome = r.on_text(encode_message(Hello(client_id="c", new_process=True))).replies[0]
    assert (welcome.last_applied_command, welcome.units_held, welcome.last_answered_comm) == (1, 0, 0)
    step = r.on_text(encode_message(Stop(command_id=3)))  # the new process's second command
    assert [c.command_id for c in step.recoveries] == [3]  # applied, not taken for the dead one's
    step = r.on_unit(encode_unit(1, 0, [Event(name="new")], True))
    assert [st.name for _, st in step.accepted] == ["new"]  # its own, whole
