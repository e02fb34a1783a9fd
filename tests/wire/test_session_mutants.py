"""Pieces of the command channel's ends (shared.wire.session) that no exchange test pinned word for
word: found by its mutation run (issue 38)."""

from __future__ import annotations

from shared.language.statements import Event
from shared.wire.messages import Accepted, Hello, Rejected, RejectReason, Stop, encode_message
from shared.wire.session import CommandReceiver, CommandSender, SessionRestart, _ranges
from shared.wire.units import encode_unit


def test_ranges_join_runs_of_consecutive_numbers():
    assert _ranges(()) == ""
    assert _ranges((5,)) == "5"
    assert _ranges((1, 2, 3, 4, 7)) == "1-4, 7"
    assert _ranges((7, 1, 3, 2, 4)) == "1-4, 7"  # in any order
    assert _ranges((2, 4, 5, 9, 10, 11, 20)) == "2, 4-5, 9-11, 20"


def test_a_restart_says_whose_fate_is_unknown():
    restart = SessionRestart(old_session="robot-a", new_session="robot-b", comms=(3, 4), commands=(7,), numbers=(1, 2, 3, 6))
    assert restart.describe() == ("robot restarted (session robot-a -> robot-b): the fate of statements 1-3, 6; "
                                  "unanswered communications 3-4; unacknowledged commands 7 is unknown")
    assert SessionRestart("a", "b", comms=(), commands=(), numbers=()).describe() == (
        "robot restarted (session a -> b): the fate of nothing is unknown")
    assert SessionRestart("a", "b", comms=(2,), commands=(), numbers=()).describe() == (
        "robot restarted (session a -> b): the fate of unanswered communications 2 is unknown")
    assert SessionRestart("a", "b", comms=(), commands=(1, 2), numbers=()).describe() == (
        "robot restarted (session a -> b): the fate of unacknowledged commands 1-2 is unknown")


def test_a_command_is_kept_until_acknowledged():
    sender = CommandSender("console-1")
    stop = sender.command(Stop)
    assert sender.unacked(stop.command_id) is stop
    assert sender.unacked(stop.command_id + 1) is None


# -- the receiver's units -----------------------------------------------------------------------

EV = Event(name="a")


def _greeted(client: str = "c", **kw) -> CommandReceiver:
    receiver = CommandReceiver("robot-1", **kw)
    receiver.on_text(encode_message(Hello(client_id=client)))
    return receiver


def test_units_before_hello_are_refused_and_the_refusal_is_not_final():
    receiver = CommandReceiver("robot-1")
    (reply,) = receiver.on_unit(encode_unit(1, 0, [EV], end=True)).replies
    assert reply == Rejected(reason=RejectReason.NO_SESSION, detail="send hello before units", final=False)


def test_a_repeat_of_an_answered_communications_last_unit_gets_its_answer_again():
    receiver = _greeted()
    step = receiver.on_unit(encode_unit(1, 0, [EV], end=False))
    assert step.replies == []
    step = receiver.on_unit(encode_unit(1, 1, [EV, EV], end=True))
    answer = step.replies[0]
    assert answer == Accepted(comm_id=1, numbers=(1, 2, 3))
    # the last unit again (its answer was lost): the same answer, nothing numbered again
    again = receiver.on_unit(encode_unit(1, 1, [EV, EV], end=True))
    assert again.replies == [answer] and again.accepted == []
    # an earlier unit of it again: nothing (the answer comes with the last unit)
    assert receiver.on_unit(encode_unit(1, 0, [EV], end=False)).replies == []
    assert receiver.next_number == 4


def test_the_statements_a_communication_numbers_are_the_senders():
    receiver = _greeted("console-7")
    receiver.on_unit(encode_unit(1, 0, [EV, EV], end=True))
    assert receiver.senders == {1: "console-7", 2: "console-7"}


def test_a_communication_may_hold_exactly_the_most_statements_and_not_one_more():
    receiver = _greeted(max_comm_statements=3)
    step = receiver.on_unit(encode_unit(1, 0, [EV, EV, EV], end=True))
    assert step.replies[0] == Accepted(comm_id=1, numbers=(1, 2, 3))
    step = receiver.on_unit(encode_unit(2, 0, [EV, EV], end=False))
    assert step.replies == []
    (refusal,) = receiver.on_unit(encode_unit(2, 1, [EV, EV], end=True)).replies
    assert refusal == Rejected(comm_id=2, seq=1, reason=RejectReason.TOO_LARGE, detail="communication over 3 statements")


def test_an_out_of_sequence_unit_names_its_place():
    receiver = _greeted()
    (reply,) = receiver.on_unit(encode_unit(2, 0, [EV], end=True)).replies
    assert reply == Rejected(comm_id=2, seq=0, reason=RejectReason.OUT_OF_SEQUENCE, final=False,
                             detail="communication 2 arrived while 1 is open")
    (reply,) = receiver.on_unit(encode_unit(1, 1, [EV], end=True)).replies
    assert reply == Rejected(comm_id=1, seq=1, reason=RejectReason.OUT_OF_SEQUENCE,
                             detail="unit 1 arrived while unit 0 was expected")


def test_a_communication_larger_than_the_buffers_room_is_refused_naming_both():
    receiver = _greeted(room=lambda: 1)
    (refusal,) = receiver.on_unit(encode_unit(1, 0, [EV, EV], end=True)).replies
    assert refusal == Rejected(comm_id=1, seq=0, reason=RejectReason.BUFFER_FULL,
                               detail="the robot's buffer has room for 1 statement(s); this communication has 2")
