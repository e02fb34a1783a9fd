"""JSON messages of the command channel: one definition each, strict parsing, no exceptions."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.wire.messages import (
    MAX_MESSAGE_BYTES,
    AbortFlush,
    Accepted,
    Hello,
    RecoveryAck,
    Rejected,
    RejectReason,
    Resume,
    RobotSnapshot,
    RobotState,
    SkipCurrent,
    StatementState,
    StatusReport,
    Stop,
    Welcome,
    decode_message,
    encode_message,
)

SNAP = RobotSnapshot(state=RobotState.IDLE, q=(0.0, 0.1, 0.2, 0.0, 0.0, 0.0), base_p_tool=(0.4, 0.1, 0.3), tool_rpy=(0.0, 3.14, 0.0))

MESSAGES = [
    Hello(client_id="console-1", last_answered_comm=3, last_report_seq=40),
    Welcome(session_id="r1", last_answered_comm=3, units_held=1, last_applied_command=0, last_report_seq=41),
    Accepted(comm_id=4, numbers=(12, 13, 14)),
    Rejected(comm_id=5, seq=0, reason=RejectReason.UNKNOWN_KIND, detail="unknown kind", statement_index=2, statement='{"kind":"X"}'),
    StatusReport(report_seq=1, number=12, state=StatementState.RECEIVED),
    StatusReport(report_seq=2, number=12, state=StatementState.DONE, robot=SNAP),
    StatusReport(report_seq=3, number=13, state=StatementState.FAILED, reason="contact before target", robot=SNAP),
    Stop(command_id=1),
    Resume(command_id=2),
    SkipCurrent(command_id=3, number=13),
    AbortFlush(command_id=4),
    RecoveryAck(command_id=4, applied=True, detail="2 statements aborted", robot=SNAP),
]


@pytest.mark.parametrize("message", MESSAGES, ids=lambda m: m.type)
def test_every_message_round_trips(message):
    assert decode_message(encode_message(message)) == message
    assert decode_message(encode_message(message).encode()) == message


def test_stop_is_marked_priority_on_the_wire():
    assert json.loads(encode_message(Stop(command_id=9))) == {"type": "stop", "command_id": 9, "priority": True}


@pytest.mark.parametrize(
    ("kwargs", "missing"),
    [({"state": StatementState.DONE}, "robot"), ({"state": StatementState.FAILED, "robot": SNAP}, "reason")],
)
def test_final_reports_carry_state_and_reason(kwargs, missing):
    with pytest.raises(ValueError, match=missing):
        StatusReport(report_seq=1, number=1, **kwargs)


def test_final_states():
    assert {s for s in StatementState if s.final} == {StatementState.DONE, StatementState.FAILED, StatementState.SKIPPED, StatementState.ABORTED}


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("not json", RejectReason.BAD_JSON),
        ("[1]", RejectReason.BAD_MESSAGE),
        ('{"type": "teleport"}', RejectReason.BAD_MESSAGE),
        ('{"type": "stop"}', RejectReason.BAD_MESSAGE),
        ('{"type": "stop", "command_id": 0}', RejectReason.BAD_MESSAGE),
        ('{"type": "stop", "command_id": 1, "extra": 2}', RejectReason.BAD_MESSAGE),
        ('{"type": "hello", "client_id": ""}', RejectReason.BAD_MESSAGE),
        ('{"type": "status", "report_seq": 1, "number": 1, "state": "done"}', RejectReason.BAD_MESSAGE),
        ("x" * (MAX_MESSAGE_BYTES + 1), RejectReason.TOO_LARGE),
        (b"\xff\xfe", RejectReason.BAD_JSON),
    ],
)
def test_malformed_messages_become_rejections(text, reason):
    result = decode_message(text)
    assert isinstance(result, Rejected) and result.reason is reason


def assert_documented_outcome(result) -> None:
    """What ``decode_message`` promises for any input: a ``Rejected`` with a reason and a detail
    saying why, or a typed message that encodes and decodes back equal."""
    if isinstance(result, Rejected) and result.comm_id is None and result.seq is None:
        assert isinstance(result.reason, RejectReason) and result.detail, result
    else:
        assert decode_message(encode_message(result)) == result


@given(st.text(max_size=300))
@settings(max_examples=300)
def test_arbitrary_text_never_raises(text):
    result = decode_message(text)  # an exception fails the test
    assert_documented_outcome(result)
    try:
        obj = json.loads(text)
    except ValueError:  # not even lenient JSON: certainly not strict JSON
        assert isinstance(result, Rejected) and result.reason is RejectReason.BAD_JSON, result
    else:
        if not isinstance(obj, dict):
            assert isinstance(result, Rejected) and result.reason in (RejectReason.BAD_JSON, RejectReason.BAD_MESSAGE), result


@given(st.dictionaries(st.sampled_from(["type", "command_id", "number", "client_id", "comm_id", "numbers"]),
                       st.none() | st.integers() | st.text(max_size=8) | st.sampled_from(["stop", "skip", "hello", "accepted"]),
                       max_size=5))
def test_arbitrary_objects_never_raise(obj):
    result = decode_message(json.dumps(obj))  # an exception fails the test
    assert_documented_outcome(result)
    if isinstance(result, Rejected):  # json.dumps of these values is strict JSON: refused as a message
        assert result.reason is RejectReason.BAD_MESSAGE, result
    else:  # a message is the type it said it was, with the fields it gave
        assert result.type == obj["type"]
        assert {k: v for k, v in obj.items() if v is not None}.items() <= json.loads(encode_message(result)).items()
