"""Command units: the framing of the command channel (thesis §4.4.1), sans-I/O.

A *communication* is a series of units; each unit is a fixed header followed by a body. The
receiver learns from the header how long the body is and whether this unit ends the
communication, then reads the body. On a WebSocket a unit is one binary message; on a byte stream
``UnitStreamDecoder`` cuts units out of arbitrary chunks.

Header (little-endian, 20 bytes, ``HEADER``)::

    offset  size  field
    0       2     magic      b"TU"
    2       1     version    1
    3       1     flags      bit 0: this unit ends the communication; other bits must be 0
    4       8     comm_id    communication number of the client, from 1 (u64)
    12      4     seq        unit number inside the communication, from 0 (u32)
    16      4     body_len   bytes of body that follow (u32)

Body: UTF-8 JSON, a list of at most ``MAX_UNIT_STATEMENTS`` statements in their JSON form
(``shared.language.statements``). An empty list is allowed (a unit that only ends a
communication). The body is decoded strictly (``shared.wire.strict_json``): NaN, Infinity, a
number that overflows or a key given twice is ``BAD_JSON``; a statement the models refuse
(beyond the bounds of ``shared.language.bounds``, a 100-character event name) is
``INVALID_STATEMENT``. Either names the statement's index in the unit and the field, as a JSON
pointer into the body (``/0/target: ...``).

Decoding never raises: every malformed input becomes a ``Rejected`` message (``shared.wire.
messages``) naming the reason and, for a bad statement, its index in the unit.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass

from pydantic import ValidationError

from shared.errors import InputError
from shared.language.json_form import JSONFormFault, loads_located, validation_faults
from shared.language.statements import Statement, program_to_json, statement_adapter
from shared.wire.messages import MAX_TEXT, Rejected, RejectReason, _one_line

HEADER = struct.Struct("<2sBBQII")
HEADER_SIZE = HEADER.size
MAGIC = b"TU"
UNIT_VERSION = 1
FLAG_END = 0x01
MAX_BODY_BYTES = 1 << 20
"""Largest body accepted (1 MiB): about 8,000 statements; a longer program takes several units."""
MAX_UNIT_STATEMENTS = 10_000
"""Most statements in one unit (``split_into_units`` puts 100 in each)."""
MAX_COMM_ID = (1 << 64) - 1
MAX_SEQ = (1 << 32) - 1
STATEMENT_KINDS = frozenset({"MOVE", "DRIVE", "DRAW", "ROTATE", "MOVES", "SPEED", "MODE", "EVENT", "TASK"})


@dataclass(frozen=True)
class UnitHeader:
    comm_id: int
    seq: int
    end: bool
    body_len: int


@dataclass(frozen=True)
class CommandUnit:
    """One decoded unit: its header fields and its statements, validated."""

    comm_id: int
    seq: int
    end: bool
    statements: tuple[Statement, ...]


def encode_unit(comm_id: int, seq: int, statements: list[Statement] | tuple[Statement, ...], end: bool) -> bytes:
    """Header plus JSON body of one unit."""
    if not 1 <= comm_id <= MAX_COMM_ID or not 0 <= seq <= MAX_SEQ:
        raise InputError(f"command unit: comm_id {comm_id} (1..{MAX_COMM_ID}) or seq {seq} (0..{MAX_SEQ}) out of range")
    body = json.dumps(program_to_json(list(statements)), separators=(",", ":")).encode("utf-8")
    if len(body) > MAX_BODY_BYTES:
        raise InputError(f"command unit: body of {len(body)} bytes is over {MAX_BODY_BYTES}; put fewer statements per unit")
    return HEADER.pack(MAGIC, UNIT_VERSION, FLAG_END if end else 0, comm_id, seq, len(body)) + body


def split_into_units(
    comm_id: int, statements: list[Statement], per_unit: int = 100
) -> list[bytes]:
    """The units of one communication: ``per_unit`` statements each, the last flagged as the end."""
    if per_unit < 1:
        raise InputError(f"command units: per_unit {per_unit} must be at least 1")
    chunks = [statements[i : i + per_unit] for i in range(0, len(statements), per_unit)] or [[]]
    return [encode_unit(comm_id, i, chunk, end=i == len(chunks) - 1) for i, chunk in enumerate(chunks)]


def decode_header(data: bytes) -> UnitHeader | Rejected:
    """The header at the start of ``data`` (which must hold at least ``HEADER_SIZE`` bytes)."""
    if len(data) < HEADER_SIZE:
        return Rejected(reason=RejectReason.BAD_HEADER, detail=f"unit of {len(data)} bytes is shorter than the {HEADER_SIZE}-byte header")
    magic, version, flags, comm_id, seq, body_len = HEADER.unpack_from(data)
    if magic != MAGIC:
        return Rejected(reason=RejectReason.BAD_HEADER, detail=f"bad magic {magic!r}; expected {MAGIC!r}")
    if version != UNIT_VERSION:
        return Rejected(reason=RejectReason.BAD_HEADER, detail=f"unit version {version}; this side speaks {UNIT_VERSION}")
    if comm_id < 1:
        return Rejected(reason=RejectReason.BAD_HEADER, detail="comm_id must be at least 1")
    if flags & ~FLAG_END:
        return Rejected(comm_id=comm_id, seq=seq, reason=RejectReason.BAD_HEADER, detail=f"unknown flag bits 0x{flags:02x}")
    if body_len > MAX_BODY_BYTES:
        return Rejected(
            comm_id=comm_id, seq=seq, reason=RejectReason.TOO_LARGE,
            detail=f"body of {body_len} bytes; limit {MAX_BODY_BYTES}",
        )
    return UnitHeader(comm_id=comm_id, seq=seq, end=bool(flags & FLAG_END), body_len=body_len)


def decode_unit(data: bytes) -> CommandUnit | Rejected:
    """One unit from one whole message: the body must be exactly ``body_len`` bytes."""
    header = decode_header(data)
    if isinstance(header, Rejected):
        return header
    got = len(data) - HEADER_SIZE
    if got != header.body_len:
        return Rejected(
            comm_id=header.comm_id, seq=header.seq, reason=RejectReason.LENGTH_MISMATCH,
            detail=f"header says {header.body_len} body bytes, unit has {got}",
        )
    return decode_body(header, bytes(data[HEADER_SIZE:]))


def decode_body(header: UnitHeader, body: bytes) -> CommandUnit | Rejected:
    """Validate the JSON body of a unit whose header is already known."""
    ids = {"comm_id": header.comm_id, "seq": header.seq}
    try:
        items = loads_located(body)
    except JSONFormFault as exc:
        index = _index_of(exc.pointer)
        return Rejected(**ids, reason=RejectReason.BAD_JSON, detail=_clip(f"body is not strict JSON: {exc}"),
                        statement_index=index, statement=None)
    if not isinstance(items, list):
        return Rejected(**ids, reason=RejectReason.BAD_BODY, detail="body is not a JSON list of statements")
    if len(items) > MAX_UNIT_STATEMENTS:
        return Rejected(**ids, reason=RejectReason.TOO_LARGE,
                        detail=f"{len(items)} statements in one unit; limit {MAX_UNIT_STATEMENTS}")
    statements: list[Statement] = []
    for index, item in enumerate(items):
        text = _snippet(item)
        if not isinstance(item, dict):
            return Rejected(**ids, reason=RejectReason.BAD_BODY, detail="a statement is not a JSON object",
                            statement_index=index, statement=text)
        kind = item.get("kind")
        if not isinstance(kind, str) or kind not in STATEMENT_KINDS:
            return Rejected(**ids, reason=RejectReason.UNKNOWN_KIND,
                            detail=f"unknown statement kind {kind!r}; valid: {', '.join(sorted(STATEMENT_KINDS))}",
                            statement_index=index, statement=text)
        try:
            statements.append(statement_adapter.validate_python(item))
        except ValidationError as exc:
            fault = validation_faults(exc, (index,))[0]
            return Rejected(**ids, reason=RejectReason.INVALID_STATEMENT, detail=_clip(f"{kind} {fault}"),
                            statement_index=index, statement=text)
        except (ValueError, TypeError) as exc:
            return Rejected(**ids, reason=RejectReason.INVALID_STATEMENT, detail=_clip(f"{kind}: {_one_line(exc)}"),
                            statement_index=index, statement=text)
    return CommandUnit(comm_id=header.comm_id, seq=header.seq, end=header.end, statements=tuple(statements))


def _index_of(pointer: str) -> int | None:
    """The statement index a pointer into the body starts with (``/3/target`` -> 3)."""
    head = pointer.split("/")[1] if pointer.startswith("/") else ""
    return int(head) if head.isdigit() and len(head) < 10 else None


def _clip(text: str) -> str:
    return text if len(text) <= MAX_TEXT else text[: MAX_TEXT - 3] + "..."


def _snippet(item: object) -> str:
    try:
        text = json.dumps(item, separators=(",", ":"))
    except (TypeError, ValueError, RecursionError):
        text = repr(item)
    return text[:200]


class UnitStreamDecoder:
    """Cuts units out of a byte stream fed in arbitrary chunks (for a plain TCP transport).

    A bad header cannot be skipped over on a stream (its length is not to be trusted), so after
    one the decoder reports it once and drops all further input; the caller closes the stream.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._header: UnitHeader | None = None
        self.broken = False

    def feed(self, data: bytes) -> list[CommandUnit | Rejected]:
        if self.broken:
            return []
        self._buffer += data
        out: list[CommandUnit | Rejected] = []
        while True:
            if self._header is None:
                if len(self._buffer) < HEADER_SIZE:
                    break
                header = decode_header(bytes(self._buffer[:HEADER_SIZE]))
                if isinstance(header, Rejected):
                    self.broken = True
                    self._buffer.clear()
                    out.append(header)
                    break
                self._header = header
                del self._buffer[:HEADER_SIZE]
            if len(self._buffer) < self._header.body_len:
                break
            body = bytes(self._buffer[: self._header.body_len])
            del self._buffer[: self._header.body_len]
            out.append(decode_body(self._header, body))
            self._header = None
        return out
