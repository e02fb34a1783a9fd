"""The writer never blocks the console and never takes it down; the reader reads what a cut-off
file still holds and says what was lost."""

from __future__ import annotations

import io
import time

import pytest

from server.recording import records
from server.recording.reader import read_recording
from server.recording.writer import RecordingWriter
from shared.errors import InputError
from support import wait_for

WAIT_S = 30.0  # a bound for a loaded 2-core machine: the writer closes the chunk within flush_s when it runs


def _write(path, n: int, **options) -> RecordingWriter:
    w = RecordingWriter(path, **options)
    w.start()
    for i in range(n):
        assert w.put("/virtual/arm", 1_000_000_000 + i * 1_000_000, {"q": [i * 0.001], "world_T_tool": [], "version": i})
    return w


def test_a_closed_file_reads_whole_in_order(tmp_path) -> None:
    stats = _write(tmp_path / "a.mcap", 500).close()
    assert stats.written == 500 and stats.dropped == 0 and stats.failed is None
    rec = read_recording(tmp_path / "a.mcap")
    assert rec.complete and rec.problem is None
    assert [m.data["version"] for m in rec.on("/virtual/arm")] == list(range(500))
    assert rec.on("/virtual/arm")[0].schema == "teleprog.VirtualArm"
    assert rec.duration_s == pytest.approx(0.499)


@pytest.mark.parametrize("keep", [0.3, 0.6, 0.95])
def test_a_file_cut_anywhere_reads_up_to_its_last_complete_chunk(tmp_path, keep: float) -> None:
    path = tmp_path / "cut.mcap"
    _write(path, 3000, chunk_size=4096).close()
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])
    rec = read_recording(path)
    assert not rec.complete
    versions = [m.data["version"] for m in rec.on("/virtual/arm")]
    assert versions == list(range(len(versions)))  # a prefix: nothing out of order, nothing invented
    assert 0 < len(versions) <= 3000  # a cut in the summary section loses no message
    assert "cut off" in rec.problem and f"{len(versions)} messages read" in rec.problem
    assert "lost" in rec.problem


def test_a_quiet_recording_closes_its_chunk_on_time_so_an_open_file_reads_what_was_put(tmp_path) -> None:
    """A handful of messages, far from filling a chunk (the count-based close) and with the file
    still open: the time-based flush (``flush_s``) closes the chunk, so a console killed now would
    leave them readable. No message is put after the first three: only the clock can close it."""
    path = tmp_path / "quiet.mcap"
    w = _write(path, 3, flush_s=0.05, chunk_size=64 * 1024 * 1024)
    try:

        def readable() -> list[int]:
            try:
                return [m.data["version"] for m in read_recording(path).on("/virtual/arm")]
            except InputError:  # nothing readable yet: the header only
                return []

        assert wait_for(readable, timeout=WAIT_S, interval=0.02, what="the three messages readable from the open file") == [0, 1, 2]
        assert not read_recording(path).complete  # still open: read from the flushed chunk, not the summary
    finally:
        w.close()


def test_a_recording_being_written_is_called_so_and_the_same_bytes_left_behind_are_cut_off(tmp_path) -> None:
    """While a console writes a file, readers (``record summary``, the replay) say it is being
    written, not cut off; the same bytes with no writer behind them (the console killed) are cut off."""
    import shutil

    from server.recording.summary import summarize, summary_lines

    path = tmp_path / "live.mcap"
    w = _write(path, 3, flush_s=0.05, chunk_size=64 * 1024 * 1024)
    try:
        wait_for(lambda: _readable(path), timeout=WAIT_S, interval=0.02, what="the flushed chunk")
        live = read_recording(path)
        assert live.writing and not live.complete and live.damage is None
        assert live.problem.startswith("live.mcap is being written (a console records into it now): 3 messages read so far")
        assert summary_lines(summarize(live))[0].endswith("3 messages (being written)")
        shutil.copyfile(path, tmp_path / "left.mcap")  # the same bytes, nobody writing them
    finally:
        w.close()
    left = read_recording(tmp_path / "left.mcap")
    assert not left.writing and not left.complete and left.problem.startswith("left.mcap was cut off")
    assert summary_lines(summarize(left))[0].endswith("(cut off)")
    closed = read_recording(path)
    assert closed.complete and not closed.writing and closed.problem is None


def _readable(path) -> bool:
    try:
        return bool(read_recording(path).messages)
    except InputError:  # the header only so far
        return False


def test_a_file_that_is_not_a_recording_is_refused_in_one_sentence(tmp_path) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"\x00" * 100)
    with pytest.raises(InputError, match="bad.mcap: not a session recording"):
        read_recording(bad)


class _FullDisk(io.RawIOBase):
    """A file on a disk that fills after ``room`` bytes."""

    def __init__(self, room: int) -> None:
        self.room, self.written = room, 0

    def writable(self) -> bool:
        return True

    def tell(self) -> int:
        return self.written

    def write(self, b) -> int:
        if self.written + len(b) > self.room:
            raise OSError(28, "No space left on device")
        self.written += len(b)
        return len(b)


def test_a_full_disk_is_reported_and_the_callers_carry_on(tmp_path) -> None:
    reported: list[str] = []
    w = RecordingWriter(tmp_path / "full.mcap", opener=lambda p: _FullDisk(2000), on_error=reported.append, flush_s=0.05,
                        chunk_size=512)
    w.start()
    deadline = time.monotonic() + 10
    while not reported and time.monotonic() < deadline:
        w.put("/virtual/arm", time.time_ns(), {"q": [0.0] * 6, "world_T_tool": [[1.0] * 4] * 4, "version": 1})
        time.sleep(0.001)
    assert reported and "No space left on device" in reported[0] and "full.mcap" in reported[0]
    assert w.failed == reported[0]
    assert w.put("/virtual/arm", time.time_ns(), {"version": 2}) is False  # refused at once, never blocks
    assert w.close().failed == reported[0]


def test_a_full_queue_drops_and_counts_instead_of_blocking(tmp_path) -> None:
    w = RecordingWriter(tmp_path / "slow.mcap", queue_size=100)
    slow = lambda: (time.sleep(2.0), {"version": 0})[1]  # noqa: E731 - a payload the writer is slow to make
    w.start()
    t0 = time.perf_counter()
    accepted = sum(w.put("/virtual/arm", 1_000 + i, slow if i == 0 else {"version": i}) for i in range(1000))
    assert time.perf_counter() - t0 < 1.0  # the callers did not wait the 2 s the writer is busy
    stats = w.close()
    assert stats.dropped == 1000 - accepted > 0
    rec = read_recording(tmp_path / "slow.mcap")
    dropped = rec.on(records.DROPPED)
    assert dropped and records.Dropped.model_validate(dropped[-1].data).total == stats.dropped
