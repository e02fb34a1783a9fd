"""The recording's writer: one MCAP file written on a thread of its own.

Callers (the console's threads) hand ``(topic, log_time_ns, payload)`` to :meth:`RecordingWriter.put`,
which never blocks and wakes nobody: the message goes on a bounded deque, and when that is full it
is dropped and counted (a ``/recording/dropped`` record says how many, once the writer catches
up). The thread wakes every ``batch_s`` (0.2 s) and writes all that waits: one wake-up per batch
instead of one per message (a wake-up per message, each a thread switch and a handover of the
interpreter lock, cost the console more than the writing did; in a running console the writer's
own CPU halved again from 20 ms batches to 100 ms). It encodes each payload (a pydantic model, or
plain data, or a callable that makes one: the costly work, such as forward kinematics, runs here
and not on the caller's thread), writes it, and closes a chunk at least every ``flush_s`` so a
console killed mid-session loses at most that much. A write that fails (a full disk) stops the
recording and is reported through ``on_error``; the console goes on.
"""

from __future__ import annotations

import ctypes
import fcntl
import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer
from pydantic import BaseModel
from pydantic_core import to_json

from server.recording import records

log = logging.getLogger(__name__)

Payload = BaseModel | dict | list | bytes | Callable[[], Any]

#: the writer thread's name in the operating system (``top -H``, ``/proc/PID/task/*/comm``)
OS_THREAD_NAME = "teleprog-record"


@dataclass(frozen=True)
class WriterStats:
    written: int
    dropped: int
    failed: str | None
    path: str
    cpu_s: float = 0.0
    """CPU time the writer's thread has spent (encoding, forward kinematics, writing), s"""


def _name_os_thread(name: str) -> None:
    """Give the calling thread ``name`` in the OS (Linux; elsewhere nothing)."""
    try:
        ctypes.CDLL(None).prctl(15, name.encode()[:15], 0, 0, 0)  # PR_SET_NAME
    except (OSError, AttributeError):
        pass


def _encode(payload: Any) -> bytes:
    """JSON of a payload: pydantic's serializer for models and for plain data alike (several
    times faster than ``json.dumps`` on the transforms' nested dicts; NaN and infinity as
    ``null``, as the models write them). Bytes pass as they are."""
    if callable(payload) and not isinstance(payload, (BaseModel, dict, list)):
        payload = payload()
    if payload is None:
        return b""
    if isinstance(payload, BaseModel):
        return payload.__pydantic_serializer__.to_json(payload)
    if isinstance(payload, bytes):
        return payload
    return to_json(payload, inf_nan_mode="null")


def _schema_for(topic: str) -> tuple[str, bytes]:
    """The schema name and its data (JSON Schema text; ``{}`` for the console's own records)."""
    name = records.TOPICS.get(topic)
    if name is None:
        name = records.event_schema(topic[len(records.EVENTS):]) if topic.startswith(records.EVENTS) else records.SCHEMA_PREFIX + "Json"
    if name.startswith("foxglove."):
        from server.recording.foxglove import schema_bytes

        return name, schema_bytes(name)
    return name, b'{"type": "object"}'


def _hold_for_writing(stream: Any) -> None:
    """Lock the open file (``flock``, exclusive) for as long as this process holds it open: a
    reader that finds the file locked knows a console is writing it now, not that one was killed
    (``server.recording.reader``). The lock goes with the process however it ends. A stream
    without a file (a test's) is not locked."""
    try:
        fcntl.flock(stream.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except (AttributeError, OSError, ValueError):
        pass


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
        batch_s: float = 0.2,
    ) -> None:
        """``opener(path)``: how the file is opened (tests hand in a stream that fails);
        ``idle()``: called on the writer's thread after each batch, returns messages that are
        due (the recorder's trailing transforms); ``batch_s``: how often the thread wakes to write
        what waits (at most ``flush_s``: a chunk is closed on time)."""
        self.path = Path(path)
        self._pending: deque = deque()
        self._queue_size = queue_size
        self._flush_s = flush_s
        self._chunk_size = chunk_size
        self._on_error = on_error
        self._opener = opener or (lambda p: open(p, "wb"))
        self._idle = idle
        self._batch_s = min(batch_s, flush_s)
        self._dropped = self._dropped_reported = 0
        self._written = 0
        self._cpu_s = 0.0
        self._failed: str | None = None
        self._closed = False
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name=f"recorder {self.path.name}", daemon=True)

    # -- the caller's side ---------------------------------------------------------------------
    def start(self) -> None:
        """Open the file and start the thread; raises ``OSError`` when the file cannot be made."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._stream = self._opener(self.path)
        _hold_for_writing(self._stream)
        self._thread.start()

    def put(self, topic: str, log_time_ns: int, payload: Payload) -> bool:
        """Queue one message; False (and counted) when the queue is full or the recording stopped.
        Never blocks and wakes no thread (``deque.append`` is atomic)."""
        if self._failed is not None or self._closed:
            return False
        if len(self._pending) >= self._queue_size:
            with self._lock:
                self._dropped += 1
            return False
        self._pending.append((topic, log_time_ns, payload))
        return True

    def close(self, timeout: float = 10.0) -> WriterStats:
        """Write what is queued, finish the file (summary and index) and stop the thread."""
        if not self._closed:
            self._closed = True
            self._stop.set()
            if self._thread.is_alive():
                self._thread.join(timeout)
        return self.stats()

    def stats(self) -> WriterStats:
        with self._lock:
            return WriterStats(self._written, self._dropped, self._failed, str(self.path), self._cpu_s)

    @property
    def failed(self) -> str | None:
        return self._failed

    # -- the thread ----------------------------------------------------------------------------
    def _run(self) -> None:
        _name_os_thread(OS_THREAD_NAME)
        cpu_start = time.thread_time()
        try:
            writer = Writer(self._stream, chunk_size=self._chunk_size, compression=CompressionType.ZSTD)
            writer.start(profile="", library="teleprog")
        except OSError as exc:
            self._fail(f"recording to {self.path} could not start: {exc}")
            return
        channels: dict[str, int] = {}
        schemas: dict[str, int] = {}
        pending = self._pending
        sequence = 0
        last_flush = time.monotonic()
        finished = False
        try:
            while True:
                stopping = self._stop.wait(self._batch_s)
                written = 0
                t_ns = 0
                while True:
                    if pending:
                        topic, t_ns, payload = pending.popleft()
                    elif self._idle is not None and (due := self._idle()):
                        pending.extend(due)
                        continue
                    else:
                        break
                    try:
                        data = _encode(payload)
                    except Exception:  # noqa: BLE001 - one bad record must not end the recording
                        log.exception("recording: could not encode a %s message", topic)
                        continue
                    if not data:
                        continue
                    channel = channels.get(topic)
                    if channel is None:
                        name, schema = _schema_for(topic)
                        if name not in schemas:
                            schemas[name] = writer.register_schema(name, "jsonschema", schema)
                        channel = channels[topic] = writer.register_channel(topic, "json", schemas[name])
                    sequence += 1
                    t_ns = int(t_ns)
                    writer.add_message(channel, log_time=t_ns, data=data, publish_time=t_ns, sequence=sequence)
                    written += 1
                    if written % 256 == 0:  # a long backlog: count as it goes, flush on time
                        self._count(written, time.thread_time() - cpu_start)
                        written = 0
                        if time.monotonic() - last_flush >= self._flush_s:
                            writer.flush()
                            last_flush = time.monotonic()
                self._count(written, time.thread_time() - cpu_start)
                if t_ns:
                    self._report_dropped(writer, channels, schemas, t_ns)
                if stopping:
                    break
                if time.monotonic() - last_flush >= self._flush_s:
                    writer.flush()
                    last_flush = time.monotonic()
            self._report_dropped(writer, channels, schemas, time.time_ns())
            writer.finish()
            finished = True
            self._count(0, time.thread_time() - cpu_start)
        except OSError as exc:  # a full disk, a vanished folder: reported, never fatal
            self._fail(f"recording to {self.path} stopped: {exc}")
        finally:
            if not finished:
                self._pending.clear()
            try:
                self._stream.close()
            except OSError:
                pass

    def _count(self, written: int, cpu_s: float) -> None:
        with self._lock:
            self._written += written
            self._cpu_s = cpu_s

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
