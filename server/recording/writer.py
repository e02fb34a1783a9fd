"""The recording's writer: one MCAP file written on a thread of its own.

Callers (the console's threads) hand ``(topic, log_time_ns, payload)`` to :meth:`RecordingWriter.put`,
which never blocks: the queue is bounded, and when it is full the message is dropped and counted
(a ``/recording/dropped`` record says how many, once the writer catches up). The thread encodes
each payload (a pydantic model, or plain data, or a callable that makes one: the costly work, such
as forward kinematics, runs here and not on the caller's thread), writes it, and closes a chunk
at least every ``flush_s`` so a console killed mid-session loses at most that much. A write that
fails (a full disk) stops the recording and is reported through ``on_error``; the console goes on.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer
from pydantic import BaseModel

from server.recording import records

log = logging.getLogger(__name__)

Payload = BaseModel | dict | list | Callable[[], Any]

_STOP = object()


@dataclass(frozen=True)
class WriterStats:
    written: int
    dropped: int
    failed: str | None
    path: str


def _encode(payload: Any) -> bytes:
    if callable(payload) and not isinstance(payload, (BaseModel, dict, list)):
        payload = payload()
    if payload is None:
        return b""
    if isinstance(payload, BaseModel):
        return payload.model_dump_json().encode()
    return json.dumps(payload, separators=(",", ":"), allow_nan=False).encode()


def _schema_for(topic: str) -> tuple[str, bytes]:
    """The schema name and its data (JSON Schema text; ``{}`` for the console's own records)."""
    name = records.TOPICS.get(topic)
    if name is None:
        name = records.event_schema(topic[len(records.EVENTS):]) if topic.startswith(records.EVENTS) else records.SCHEMA_PREFIX + "Json"
    if name.startswith("foxglove."):
        from server.recording.foxglove import schema_bytes

        return name, schema_bytes(name)
    return name, b'{"type": "object"}'


class RecordingWriter:
    """One MCAP file, written by a daemon thread (see the module docstring)."""

    def __init__(
        self,
        path: Path,
        *,
        queue_size: int = 20_000,
        flush_s: float = 1.0,
        chunk_size: int = 512 * 1024,
        on_error: Callable[[str], None] | None = None,
        opener: Callable[[Path], Any] | None = None,
        idle: Callable[[], list[tuple[str, int, Payload]]] | None = None,
        idle_s: float = 0.05,
    ) -> None:
        """``opener(path)``: how the file is opened (tests hand in a stream that fails);
        ``idle()``: called on the writer's thread at least every ``idle_s``, returns messages
        that are due (the recorder's trailing transforms)."""
        self.path = Path(path)
        self._queue: queue.Queue = queue.Queue(maxsize=queue_size)
        self._flush_s = flush_s
        self._chunk_size = chunk_size
        self._on_error = on_error
        self._opener = opener or (lambda p: open(p, "wb"))
        self._idle, self._idle_s = idle, idle_s
        self._dropped = self._dropped_reported = 0
        self._written = 0
        self._failed: str | None = None
        self._closed = False
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name=f"recorder {self.path.name}", daemon=True)
        self._started = threading.Event()
        self._open_error: str | None = None

    # -- the caller's side ---------------------------------------------------------------------
    def start(self) -> None:
        """Open the file and start the thread; raises ``OSError`` when the file cannot be made."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._stream = self._opener(self.path)
        self._thread.start()

    def put(self, topic: str, log_time_ns: int, payload: Payload) -> bool:
        """Queue one message; False (and counted) when the queue is full or the recording stopped."""
        if self._failed is not None or self._closed:
            return False
        try:
            self._queue.put_nowait((topic, int(log_time_ns), payload))
            return True
        except queue.Full:
            with self._lock:
                self._dropped += 1
            return False

    def close(self, timeout: float = 10.0) -> WriterStats:
        """Write what is queued, finish the file (summary and index) and stop the thread."""
        if not self._closed:
            self._closed = True
            if self._thread.is_alive():
                while True:  # the stop marker must get in even when the queue is full
                    try:
                        self._queue.put(_STOP, timeout=0.1)
                        break
                    except queue.Full:
                        if not self._thread.is_alive():
                            break
                self._thread.join(timeout)
        return self.stats()

    def stats(self) -> WriterStats:
        with self._lock:
            return WriterStats(self._written, self._dropped, self._failed, str(self.path))

    @property
    def failed(self) -> str | None:
        return self._failed

    # -- the thread ----------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            writer = Writer(self._stream, chunk_size=self._chunk_size, compression=CompressionType.ZSTD)
            writer.start(profile="", library="teleprog")
        except OSError as exc:
            self._fail(f"recording to {self.path} could not start: {exc}")
            return
        channels: dict[str, int] = {}
        schemas: dict[str, int] = {}
        sequence = 0
        last_flush = time.monotonic()
        finished = False
        try:
            while True:
                timeout = max(0.0, self._flush_s - (time.monotonic() - last_flush))
                if self._idle is not None:
                    timeout = min(timeout, self._idle_s)
                try:
                    item = self._queue.get(timeout=timeout)
                except queue.Empty:
                    item = None
                if item is _STOP:
                    break
                due = self._idle() if self._idle is not None else []
                for topic, t_ns, payload in [*([item] if item is not None else []), *due]:
                    try:
                        data = _encode(payload)
                    except Exception:  # noqa: BLE001 - one bad record must not end the recording
                        log.exception("recording: could not encode a %s message", topic)
                        continue
                    if data:
                        channel = channels.get(topic)
                        if channel is None:
                            name, schema = _schema_for(topic)
                            if name not in schemas:
                                schemas[name] = writer.register_schema(name, "jsonschema", schema)
                            channel = channels[topic] = writer.register_channel(topic, "json", schemas[name])
                        sequence += 1
                        writer.add_message(channel, log_time=t_ns, data=data, publish_time=t_ns, sequence=sequence)
                        with self._lock:
                            self._written += 1
                    self._report_dropped(writer, channels, schemas, t_ns)
                if time.monotonic() - last_flush >= self._flush_s:
                    writer.flush()
                    last_flush = time.monotonic()
            self._report_dropped(writer, channels, schemas, time.time_ns())
            writer.finish()
            finished = True
        except OSError as exc:  # a full disk, a vanished folder: reported, never fatal
            self._fail(f"recording to {self.path} stopped: {exc}")
        finally:
            if not finished:
                self._drain()
            try:
                self._stream.close()
            except OSError:
                pass

    def _report_dropped(self, writer: Writer, channels: dict[str, int], schemas: dict[str, int], t_ns: int) -> None:
        with self._lock:
            new = self._dropped - self._dropped_reported
            if new <= 0:
                return
            self._dropped_reported = self._dropped
            total = self._dropped
        topic = records.DROPPED
        if topic not in channels:
            name, schema = _schema_for(topic)
            if name not in schemas:
                schemas[name] = writer.register_schema(name, "jsonschema", schema)
            channels[topic] = writer.register_channel(topic, "json", schemas[name])
        writer.add_message(channels[topic], log_time=t_ns, data=_encode(records.Dropped(count=new, total=total)), publish_time=t_ns)
        log.warning("recording fell behind: %d messages dropped (%d in all)", new, total)

    def _fail(self, message: str) -> None:
        self._failed = message
        log.error("%s", message)
        if self._on_error is not None:
            try:
                self._on_error(message)
            except Exception:  # noqa: BLE001
                log.exception("reporting a recording failure failed")

    def _drain(self) -> None:
        while True:
            try:
                self._queue.get_nowait()
            except queue.Empty:
                return
