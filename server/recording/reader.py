"""Reading a session recording back, whole, cut off or damaged.

``read_recording(path)`` reads every complete record in file order. A file whose writer was killed
(or whose disk filled) ends inside a chunk: what came before is read, the rest is named in
``Recording.problem`` (how many bytes could not be read and the last time that was read), never
raised. A damaged file (a bit flipped on disk: a chunk whose checksum or zstd decompression fails,
a record that does not parse) is read around the damage where MCAP's framing allows, and
``Recording.problem`` starts ``<file>: damaged recording: ...``; every decompression and format
error stops here, as a sentence. A file that is not a recording at all, or a damaged one of which
no message can be read, raises ``InputError`` with a sentence that says so. Only regular files are
read: a FIFO, a device or a folder is refused without being opened (``shared.files``).
"""

from __future__ import annotations

import fcntl
import json
import logging
import struct
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, BinaryIO

from mcap.exceptions import EndOfFile, InvalidMagic, McapError, RecordLengthLimitExceeded, UnsupportedCompressionError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Schema
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from pydantic import ValidationError
from zstandard import ZstdError

from server.recording import records
from shared.errors import InputError
from shared.files import open_regular, regular_file

log = logging.getLogger(__name__)

SUFFIX = ".mcap"


@dataclass(frozen=True)
class RecordedMessage:
    topic: str
    schema: str
    log_time_ns: int
    data: Any
    """the decoded JSON payload"""

    @property
    def t(self) -> float:
        """Unix seconds."""
        return self.log_time_ns * 1e-9


@dataclass
class Recording:
    """A recording's messages in time order, and what could not be read."""

    path: Path
    messages: list[RecordedMessage]
    complete: bool
    """the console closed the file: its footer was read (or, in a damaged file, its data section was
    read to its end and the file ends as a closed one does)"""
    problem: str | None = None
    """what was lost, in a sentence (None: nothing)"""
    damage: str | None = None
    """what of the file is damaged (a chunk that fails its checksum or decompression), in a
    sentence without the file's name; None when nothing is (a cut-off file is not damaged)"""
    writing: bool = False
    """a console is writing the file now (it holds the writer's lock): not closed yet, not cut off"""
    _by_topic: dict[str, list[RecordedMessage]] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        for m in self.messages:
            self._by_topic.setdefault(m.topic, []).append(m)

    def on(self, topic: str) -> list[RecordedMessage]:
        """The messages of one topic, in time order."""
        return self._by_topic.get(topic, [])

    @property
    def topics(self) -> list[str]:
        return sorted(self._by_topic)

    def counts(self) -> dict[str, int]:
        return dict(sorted(Counter(m.topic for m in self.messages).items()))

    @property
    def start_ns(self) -> int:
        return self.messages[0].log_time_ns if self.messages else 0

    @property
    def end_ns(self) -> int:
        return self.messages[-1].log_time_ns if self.messages else 0

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) * 1e-9

    @property
    def session(self) -> records.SessionStart | None:
        first = self.on(records.SESSION)
        if not first:
            return None
        try:
            return records.SessionStart.model_validate(first[0].data)
        except ValidationError as exc:
            raise InputError(f"{self.path}: damaged recording: its session start is not one the console writes "
                             f"({_first_error(exc)})") from None


def _first_error(exc: ValidationError) -> str:
    """The first thing a record's validation refused: where and what, never the value."""
    err = exc.errors()[0]
    return f"{'.'.join(str(p) for p in err.get('loc', ())) or 'the record'}: {err.get('msg', 'invalid')}"


def _when(t_ns: int) -> str:
    return datetime.fromtimestamp(t_ns * 1e-9, tz=timezone.utc).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3] + " UTC"


MAGIC = b"\x89MCAP0\r\n"
"""MCAP's first and last eight bytes: a file that ends with them was closed by its writer."""

MAX_CHUNK_BYTES = 256 * 1024 * 1024
"""Largest uncompressed chunk read (the writer closes chunks at 512 KiB): a larger size is damage,
never memory to allocate."""

_FORMAT_ERRORS = (McapError, ZstdError, struct.error, ValueError, EOFError, OverflowError, MemoryError, RuntimeError,
                  KeyError, IndexError, TypeError)
"""What decoding a damaged or cut-off MCAP file raises (in the mcap library, zstandard or lz4)."""


class _Bounded:
    """The file as the MCAP reader sees it: a read never asks for more than the file has left, so
    that a damaged length field cannot make it allocate gigabytes."""

    def __init__(self, raw: BinaryIO, size: int) -> None:
        self._raw, self._size, self._pos = raw, size, 0

    def read(self, n: int = -1) -> bytes:
        left = max(0, self._size - self._pos)
        data = self._raw.read(left if n is None or n < 0 or n > left else n)
        self._pos += len(data)
        return data

    def tell(self) -> int:
        return self._pos


def _why(exc: BaseException) -> str:
    """What went wrong, in words, never quoting the file's bytes."""
    if isinstance(exc, CRCValidationError):
        return f"its {type(exc.record).__name__.lower()} checksum does not match"
    if isinstance(exc, ZstdError):
        return f"zstd cannot decompress it ({str(exc).removeprefix('decompression error: ') or 'corrupt data'})"
    if isinstance(exc, InvalidMagic):
        return "it does not begin with MCAP's magic bytes"
    if isinstance(exc, (EndOfFile, EOFError)):
        return "the file ends inside it"
    if isinstance(exc, (RecordLengthLimitExceeded, UnsupportedCompressionError)):
        return str(exc)
    if isinstance(exc, MemoryError):
        return "it claims more memory than there is"
    return f"its bytes do not parse ({type(exc).__name__})"


def _chunk_records(chunk: Chunk) -> list[object]:
    if chunk.uncompressed_size > MAX_CHUNK_BYTES:
        raise RecordLengthLimitExceeded(Opcode.CHUNK, chunk.uncompressed_size, MAX_CHUNK_BYTES)
    return breakup_chunk(chunk, validate_crc=True)


def _not_a_recording(path: Path, size: int, failure: BaseException | None) -> InputError:
    if size == 0:
        why = "the file is empty (0 bytes); a recording begins with MCAP's magic bytes and a header record"
    elif isinstance(failure, InvalidMagic) or size < len(MAGIC):
        why = "it does not begin with MCAP's magic bytes"
    elif isinstance(failure, (EndOfFile, EOFError)):
        why = f"it ends after {size} bytes, before its header record is whole"
    elif failure is not None:
        why = f"its header record cannot be read: {_why(failure)}"
    else:
        why = "it holds no MCAP record"
    return InputError(f"{path}: not a session recording (MCAP): {why}")


def read_recording(path: str | Path) -> Recording:
    """Read ``path`` (see the module docstring). A damaged file (a chunk whose checksum or
    compression fails, a record that does not parse before the file's end) is read around the
    damage where it can be, and ``Recording.damage`` and ``problem`` say what was lost; one where
    no message can be read raises ``InputError`` (``<file>: damaged recording: ...``)."""
    path = Path(path)
    raw, size = open_regular(path, "recording")  # a FIFO, a device or a folder is refused unopened
    writing = being_written(raw)
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    messages: list[RecordedMessage] = []
    bad_payloads = 0
    complete = False
    failure: BaseException | None = None
    skipped: list[tuple[int, int, str]] = []  # damaged chunks: (byte, length, why)

    def take(record: object) -> None:
        nonlocal bad_payloads
        if isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Channel):
            channels[record.id] = (record.topic, schemas.get(record.schema_id, ""))
        elif isinstance(record, Message):
            topic, schema = channels.get(record.channel_id, (f"channel {record.channel_id}", ""))
            try:
                data = json.loads(record.data)
            except ValueError:
                bad_payloads += 1
                return
            messages.append(RecordedMessage(topic, schema, record.log_time, data))

    with raw:
        closed = False
        if size >= 2 * len(MAGIC):
            try:
                raw.seek(size - len(MAGIC))
                closed = raw.read(len(MAGIC)) == MAGIC
                raw.seek(0)
            except OSError as exc:
                raise InputError(f"{path}: cannot read the recording: {exc.strerror or type(exc).__name__}") from None
        stream = _Bounded(raw, size)
        # no length limit of its own: ``_Bounded`` never reads past the end, and a record longer than
        # what is left reads as a file cut inside it
        reader = StreamReader(stream, emit_chunks=True, validate_crcs=True, record_size_limit=None)
        good_until = 0
        try:
            for record in reader.records:
                if isinstance(record, Chunk):
                    try:
                        inner = _chunk_records(record)
                    except _FORMAT_ERRORS as exc:
                        skipped.append((good_until, stream.tell() - good_until, _why(exc)))
                        inner = []
                    for one in inner:
                        take(one)
                else:
                    take(record)
                good_until = stream.tell()
                if isinstance(record, Footer):
                    complete = True
        except OSError as exc:
            raise InputError(f"{path}: cannot read the recording: {exc.strerror or type(exc).__name__}") from None
        except _FORMAT_ERRORS as exc:
            failure = exc
    if failure is not None and not messages and not skipped and good_until <= len(MAGIC):
        raise _not_a_recording(path, size, failure)
    messages.sort(key=lambda m: m.log_time_ns)  # chunks are written in time order; sort is stable
    last = f"the last message read is from {_when(messages[-1].log_time_ns)}" if messages else "no message could be read"
    damage: list[str] = []
    if skipped:
        at, length, why = skipped[0]
        more = f" and {len(skipped) - 1} more" if len(skipped) > 1 else ""
        damage.append(f"the chunk at byte {at} ({length} bytes{more}) cannot be read: {why}; what it held is skipped")
    if failure is not None:
        if isinstance(failure, CRCValidationError) and isinstance(failure.record, DataEnd):
            complete = closed  # every record was read; the data section's checksum names damage
            if not skipped:
                damage.append("the data section's checksum does not match (a record outside the chunks is damaged)")
        elif stream.tell() >= size and not closed:  # the writer stopped inside it: killed, or the disk filled
            log.info("reading %s stopped at byte %d: %s", path, good_until, _why(failure))
            if damage:
                damage.append(f"the file is also cut off after byte {good_until} (the console did not close it)")
        else:
            damage.append(f"the record at byte {good_until} cannot be read: {_why(failure)}; "
                          f"the {size - good_until} bytes from there on are skipped")
    problem = None
    if damage:
        if not messages:
            raise InputError(f"{path}: damaged recording: {'; '.join(damage)}; no message could be read")
        problem = f"{path.name}: damaged recording: {'; '.join(damage)}; {len(messages)} messages read, {last}"
    elif not complete and writing:
        problem = (f"{path.name} is being written (a console records into it now): {len(messages)} messages "
                   f"read so far; {last}")
    elif not complete:
        lost = max(0, size - good_until)
        problem = (f"{path.name} was cut off (the console did not close it: killed, or the disk filled): "
                   f"{len(messages)} messages read, {lost} bytes after the last complete chunk lost; {last}")
    if bad_payloads:
        extra = f"{bad_payloads} messages had payloads that are not JSON and were skipped"
        problem = f"{problem}; {extra}" if problem else f"{path.name}: {extra}"
    return Recording(path=path, messages=messages, complete=complete, problem=problem,
                     damage="; ".join(damage) or None, writing=writing and not complete)


def being_written(stream: BinaryIO) -> bool:
    """Whether a console holds the file open to write it (``RecordingWriter`` locks it while it
    writes; the lock goes with its process, however that ends)."""
    try:
        fcntl.flock(stream.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except (AttributeError, OSError, ValueError):
        return False
    fcntl.flock(stream.fileno(), fcntl.LOCK_UN)
    return False


@dataclass(frozen=True)
class RecordingInfo:
    """One recording in a folder (``GET /api/sessions``)."""

    name: str
    path: str
    size: int
    modified: float


def list_recordings(folder: str | Path) -> list[RecordingInfo]:
    """The ``.mcap`` files of ``folder``, newest first (none when the folder does not exist): only
    regular files that stay inside the folder (not a FIFO, nor a symlink leading out)."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    root = folder.resolve()
    found = []
    for p in folder.glob(f"*{SUFFIX}"):
        try:
            st = regular_file(p)
            real = p.resolve()
        except (InputError, OSError, RuntimeError):
            continue
        if root not in real.parents:
            continue
        found.append(RecordingInfo(p.name, str(real), st.st_size, st.st_mtime))
    return sorted(found, key=lambda r: r.modified, reverse=True)
