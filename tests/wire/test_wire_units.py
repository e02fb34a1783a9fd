"""Command-unit framing: round trips, and every kind of malformed unit becomes a typed rejection."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.errors import InputError
from shared.language.statements import Drive, Event, Move, SetSpeed, Speed, SpeedUnit, TaskCall, program_to_json
from shared.wire.messages import Rejected, RejectReason
from shared.wire.units import (
    HEADER,
    FLAG_END,
    HEADER_SIZE,
    MAGIC,
    MAX_BODY_BYTES,
    UNIT_VERSION,
    CommandUnit,
    UnitStreamDecoder,
    decode_unit,
    encode_unit,
    split_into_units,
)

PROGRAM = [
    Move(joints=(0.0, -0.5, 1.2, 0.0, 0.3, 0.0)),
    SetSpeed(speed=Speed(value=0.5, unit=SpeedUnit.FRACTION)),
    Drive(joint=3, target=-0.52),
    Event(name="above_peg"),
    TaskCall(name="insert_peg", args=("PEG", "HOLE1")),
]


def _raw_unit(body: bytes, comm_id: int = 1, seq: int = 0, flags: int = 1, length: int | None = None) -> bytes:
    return HEADER.pack(b"TU", 1, flags, comm_id, seq, len(body) if length is None else length) + body


def test_round_trip_keeps_header_and_statements():
    data = encode_unit(7, 3, PROGRAM, end=True)
    unit = decode_unit(data)
    assert isinstance(unit, CommandUnit)
    assert (unit.comm_id, unit.seq, unit.end) == (7, 3, True)
    assert list(unit.statements) == PROGRAM


def test_body_is_the_json_form_of_statements():
    data = encode_unit(1, 0, PROGRAM, end=False)
    assert json.loads(data[HEADER_SIZE:]) == program_to_json(PROGRAM)
    assert HEADER.unpack_from(data)[-1] == len(data) - HEADER_SIZE


def test_split_marks_only_the_last_unit_as_the_end():
    units = [decode_unit(u) for u in split_into_units(4, PROGRAM * 5, per_unit=7)]
    assert [u.seq for u in units] == [0, 1, 2, 3]
    assert [u.end for u in units] == [False, False, False, True]
    assert [s for u in units for s in u.statements] == PROGRAM * 5


def test_empty_communication_is_one_empty_end_unit():
    (data,) = split_into_units(1, [])
    unit = decode_unit(data)
    assert unit.end and unit.statements == ()


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"", RejectReason.BAD_HEADER),
        (b"TU\x01", RejectReason.BAD_HEADER),
        (_raw_unit(b"[]")[:-3], RejectReason.BAD_HEADER),
        (b"XX" + _raw_unit(b"[]")[2:], RejectReason.BAD_HEADER),
        (HEADER.pack(b"TU", 9, 1, 1, 0, 2) + b"[]", RejectReason.BAD_HEADER),
        (_raw_unit(b"[]", flags=0x81), RejectReason.BAD_HEADER),
        (_raw_unit(b"[]", comm_id=0), RejectReason.BAD_HEADER),
        (_raw_unit(b"[]", length=3), RejectReason.LENGTH_MISMATCH),
        (_raw_unit(b"[] ", length=2), RejectReason.LENGTH_MISMATCH),
        (_raw_unit(b"", length=MAX_BODY_BYTES + 1), RejectReason.TOO_LARGE),
        (_raw_unit(b"[{"), RejectReason.BAD_JSON),
        (_raw_unit(b"\xff\xfe[]"), RejectReason.BAD_JSON),
        (_raw_unit(b"[" * 100_000), RejectReason.BAD_JSON),
        (_raw_unit(b'{"kind": "MOVE"}'), RejectReason.BAD_BODY),
        (_raw_unit(b"[1, 2]"), RejectReason.BAD_BODY),
        (_raw_unit(b'[{"kind": "JUMP", "to": 3}]'), RejectReason.UNKNOWN_KIND),
        (_raw_unit(b'[{"joint": 1}]'), RejectReason.UNKNOWN_KIND),
        (_raw_unit(b'[{"kind": "DRIVE", "joint": 0, "target": 1.0}]'), RejectReason.INVALID_STATEMENT),
        (_raw_unit(b'[{"kind": "DRIVE", "joint": 1, "target": 1.0, "extra": 1}]'), RejectReason.INVALID_STATEMENT),
        (_raw_unit(b'[{"kind": "EVENT", "name": "1 bad"}]'), RejectReason.INVALID_STATEMENT),
    ],
)
def test_malformed_units_are_rejected_with_the_reason(data, reason):
    result = decode_unit(data)
    assert isinstance(result, Rejected)
    assert result.reason is reason, result.detail
    assert result.detail


def test_rejection_names_the_offending_statement():
    body = json.dumps(program_to_json(PROGRAM[:2]) + [{"kind": "DRIVE", "joint": "three", "target": 0}]).encode()
    result = decode_unit(_raw_unit(body, comm_id=5, seq=2))
    assert isinstance(result, Rejected)
    assert (result.comm_id, result.seq, result.statement_index) == (5, 2, 2)
    assert result.reason is RejectReason.INVALID_STATEMENT
    assert '"three"' in result.statement


def test_huge_body_is_refused_from_the_header_alone():
    # the header claims 100 MB: refused before any body is awaited or parsed
    decoder = UnitStreamDecoder()
    (result,) = decoder.feed(_raw_unit(b"", length=100_000_000))
    assert isinstance(result, Rejected) and result.reason is RejectReason.TOO_LARGE
    assert decoder.broken and decoder.feed(encode_unit(1, 0, PROGRAM, True)) == []


@given(st.one_of(st.binary(max_size=400), st.binary(max_size=300).map(_raw_unit)))
@settings(max_examples=300)
def test_arbitrary_bytes_are_refused_for_their_first_fault(data):
    """Any bytes, bare or behind a good header: the answer is the first fault's rejection (the
    header, then its length, then the body's JSON), and a unit only for a JSON list."""
    result = decode_unit(data)
    if len(data) < HEADER_SIZE:
        assert isinstance(result, Rejected) and result.reason is RejectReason.BAD_HEADER and "shorter than" in result.detail
        return
    magic, version, flags, comm_id, seq, body_len = HEADER.unpack_from(data)
    body = data[HEADER_SIZE:]
    if magic != MAGIC or version != UNIT_VERSION or comm_id < 1 or flags & ~FLAG_END:
        assert isinstance(result, Rejected) and result.reason is RejectReason.BAD_HEADER
    elif body_len > MAX_BODY_BYTES:
        assert isinstance(result, Rejected) and result.reason is RejectReason.TOO_LARGE
    elif len(body) != body_len:
        assert isinstance(result, Rejected) and result.reason is RejectReason.LENGTH_MISMATCH
    else:
        assert (result.comm_id, result.seq) == (comm_id, seq)
        try:
            document = json.loads(body.decode("utf-8"))
        except ValueError:  # not UTF-8, or not JSON at all: refused as such
            assert isinstance(result, Rejected) and result.reason is RejectReason.BAD_JSON
            return
        if isinstance(result, CommandUnit):
            assert isinstance(document, list) and len(result.statements) == len(document)
            assert result.end == bool(flags & FLAG_END)
        else:  # strict JSON refuses more than Python's json (NaN, 1e999, a repeated key)
            assert result.reason in (RejectReason.BAD_JSON, RejectReason.BAD_BODY, RejectReason.UNKNOWN_KIND,
                                     RejectReason.INVALID_STATEMENT)
            if result.reason is RejectReason.BAD_BODY and not isinstance(document, list):
                assert result.detail == "body is not a JSON list of statements"


@given(st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
                    lambda c: st.lists(c, max_size=4) | st.dictionaries(st.sampled_from(["kind", "joint", "target", "name", "x"]), c, max_size=4),
                    max_leaves=20))
@settings(max_examples=300)
def test_arbitrary_json_bodies_never_raise(obj):
    body = json.dumps(obj).encode()
    assert isinstance(decode_unit(_raw_unit(body)), (CommandUnit, Rejected))


@given(st.lists(st.integers(min_value=1, max_value=64), min_size=1, max_size=30))
def test_stream_decoder_reassembles_any_chunking(cuts):
    stream = b"".join(split_into_units(2, PROGRAM * 3, per_unit=4))
    decoder = UnitStreamDecoder()
    units, pos, i = [], 0, 0
    while pos < len(stream):
        n = cuts[i % len(cuts)]
        units += decoder.feed(stream[pos : pos + n])
        pos, i = pos + n, i + 1
    assert all(isinstance(u, CommandUnit) for u in units)
    assert [s for u in units for s in u.statements] == PROGRAM * 3
    assert [u.end for u in units] == [False, False, False, True]


def test_encode_refuses_out_of_range_numbers_and_oversized_bodies():
    with pytest.raises(InputError):
        encode_unit(0, 0, PROGRAM, True)
    with pytest.raises(InputError):
        encode_unit(1, -1, PROGRAM, True)
    with pytest.raises(InputError, match="fewer statements"):
        encode_unit(1, 0, PROGRAM * 20_000, True)
    with pytest.raises(InputError):
        split_into_units(1, PROGRAM, per_unit=0)
