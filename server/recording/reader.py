"""Reading a session recording back, whole or cut off.

``read_recording(path)`` reads every complete record in file order. A file whose writer was killed
(or whose disk filled) ends inside a chunk: what came before is read, the rest is named in
``Recording.problem`` (how many bytes could not be read and the last time that was read), never
raised. A file that is not a recording at all raises ``InputError`` with a sentence that says so.
"""

from __future__ import annotations

import json
import logging
import struct
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from server.recording import records
from shared.errors import InputError

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
    """the file ends with MCAP's footer: the console closed it"""
    problem: str | None = None
    """what was lost, in a sentence (None: nothing)"""
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
        return records.SessionStart.model_validate(first[0].data) if first else None


def _when(t_ns: int) -> str:
    return datetime.fromtimestamp(t_ns * 1e-9, tz=timezone.utc).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3] + " UTC"


def read_recording(path: str | Path) -> Recording:
    """Read ``path`` (see the module docstring)."""
    path = Path(path)
    try:
        size = path.stat().st_size
        stream = open(path, "rb")
    except OSError as exc:
        raise InputError(f"{path}: cannot read the recording: {exc.strerror or exc}") from None
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    messages: list[RecordedMessage] = []
    bad_payloads = 0
    complete = False
    cut: str | None = None

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

    with stream:
        reader = StreamReader(stream, emit_chunks=True, validate_crcs=True)
        records_iter = reader.records
        good_until = 0
        try:
            for record in records_iter:
                if isinstance(record, Chunk):
                    for inner in breakup_chunk(record, validate_crc=True):
                        take(inner)
                else:
                    take(record)
                good_until = stream.tell()
                if isinstance(record, Footer):
                    complete = True
        except (McapError, ValueError, EOFError, OSError, MemoryError, struct.error) as exc:
            if not messages and good_until <= 8:
                raise InputError(f"{path}: not a session recording (MCAP): {exc}") from None
            cut = str(exc) or type(exc).__name__
    messages.sort(key=lambda m: m.log_time_ns)  # chunks are written in time order; sort is stable
    problem = None
    if not complete:
        lost = max(0, size - good_until)
        last = f"the last message read is from {_when(messages[-1].log_time_ns)}" if messages else "no message could be read"
        problem = (f"{path.name} was cut off (the console did not close it: killed, or the disk filled): "
                   f"{len(messages)} messages read, {lost} bytes after the last complete chunk lost; {last}")
        if cut:
            log.info("reading %s stopped at byte %d: %s", path, good_until, cut)
    if bad_payloads:
        extra = f"{bad_payloads} messages had payloads that are not JSON and were skipped"
        problem = f"{problem}; {extra}" if problem else f"{path.name}: {extra}"
    return Recording(path=path, messages=messages, complete=complete, problem=problem)


@dataclass(frozen=True)
class RecordingInfo:
    """One recording in a folder (``GET /api/sessions``)."""

    name: str
    path: str
    size: int
    modified: float


def list_recordings(folder: str | Path) -> list[RecordingInfo]:
    """The ``.mcap`` files of ``folder``, newest first (none when the folder does not exist)."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    found = []
    for p in folder.glob(f"*{SUFFIX}"):
        try:
            st = p.stat()
        except OSError:
            continue
        found.append(RecordingInfo(p.name, str(p.resolve()), st.st_size, st.st_mtime))
    return sorted(found, key=lambda r: r.modified, reverse=True)
