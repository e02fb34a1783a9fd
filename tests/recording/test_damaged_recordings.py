"""A damaged recording (bits flipped on disk) reads as one sentence, never a decompressor's
traceback: ``<file>: damaged recording: ...``. What the damage spares is read (MCAP's chunks are
independent); when nothing is, the reader, ``teleprog record summary`` and the replay refuse it in
one line. An empty or magic-only file says what is missing instead of ending in a bare colon."""

from __future__ import annotations

import io
import random
import subprocess
import sys
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
from test_replay_paths import write_recording

from server.recording.reader import MAGIC, read_recording
from server.recording.summary import summarize
from server.replay.app import create_replay_app
from server.replay.player import open_replay
from shared.errors import InputError
from shared.paths import PROJECT_DIR

CHUNK_HEAD = 1 + 8 + 8 + 8 + 8 + 4 + 4 + len("zstd") + 8
"""Bytes from a chunk record's opcode to its compressed data: opcode, length, start and end
times, uncompressed size and CRC, the compression's name and the data's length."""


def chunk_data_offsets(data: bytes) -> list[tuple[int, int]]:
    """(offset, length) of each chunk's compressed data in an MCAP file."""
    stream = io.BytesIO(data)
    found, before = [], 0
    for record in StreamReader(stream, emit_chunks=True).records:
        if isinstance(record, Chunk):
            assert record.compression == "zstd"
            found.append((before + CHUNK_HEAD, len(record.data)))
        before = stream.tell()
    return found


@pytest.fixture(scope="module")
def chunked(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A recording of many small chunks (the session start in the first)."""
    path = write_recording(tmp_path_factory.mktemp("damaged") / "chunked.mcap", n=400, chunk_size=2048)
    assert len(chunk_data_offsets(path.read_bytes())) >= 5
    return path


def damaged(source: Path, out: Path, chunk: int, how: str) -> Path:
    data = bytearray(source.read_bytes())
    offset, length = chunk_data_offsets(bytes(data))[chunk]
    if how == "zstd-magic":  # the frame no longer starts with zstd's magic: ZstdError
        data[offset] ^= 0xFF
    else:  # one bit of the compressed middle: zstd fails, or the chunk's CRC does
        data[offset + length // 2] ^= 0x10
    out.write_bytes(bytes(data))
    return out


@pytest.mark.parametrize("how", ["zstd-magic", "bit"])
def test_a_damaged_chunk_is_skipped_and_named(chunked: Path, tmp_path: Path, how: str) -> None:
    whole = read_recording(chunked)
    path = damaged(chunked, tmp_path / "flipped.mcap", 2, how)
    rec = read_recording(path)
    assert rec.problem.startswith("flipped.mcap: damaged recording: the chunk at byte ")
    assert "cannot be read" in rec.problem and "\n" not in rec.problem
    assert rec.damage and rec.complete  # the console closed it: damaged, not cut off
    assert 0 < len(rec.messages) < len(whole.messages)
    versions = [m.data["version"] for m in rec.on("/virtual/arm")]
    assert versions == sorted(versions)  # what was read is in order, nothing invented
    assert summarize(rec).messages == len(rec.messages)
    opened = open_replay(path)  # the session start is in the first chunk, intact
    assert opened.recording.damage


def test_a_recording_damaged_where_it_starts_is_refused_in_one_line(chunked: Path, tmp_path: Path) -> None:
    path = damaged(chunked, tmp_path / "head.mcap", 0, "zstd-magic")
    with pytest.raises(InputError, match=r"head\.mcap: damaged recording: .*zstd cannot decompress it.*session start"):
        open_replay(path)


def test_a_recording_with_nothing_readable_is_refused_as_damaged(tmp_path: Path) -> None:
    one = write_recording(tmp_path / "one.mcap", n=3)
    assert len(chunk_data_offsets(one.read_bytes())) == 1
    path = damaged(one, tmp_path / "nothing.mcap", 0, "zstd-magic")
    with pytest.raises(InputError, match=r"nothing\.mcap: damaged recording: .*; no message could be read$"):
        read_recording(path)


def test_empty_and_magic_only_files_say_what_is_missing(tmp_path: Path) -> None:
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    magic = tmp_path / "magic.mcap"
    magic.write_bytes(MAGIC)
    for path, says in ((empty, "the file is empty"), (magic, "before its header record is whole")):
        with pytest.raises(InputError) as exc:
            read_recording(path)
        message = str(exc.value)
        assert "not a session recording (MCAP): " in message and says in message
        assert not message.rstrip().endswith(":")


def test_random_damage_never_escapes_as_anything_but_a_sentence(chunked: Path, tmp_path: Path) -> None:
    """Bit flips, overwritten runs and cuts anywhere in the file: every outcome is a recording
    (maybe with its problem named) or an ``InputError``, never another exception."""
    source = chunked.read_bytes()
    rnd = random.Random(36)
    path = tmp_path / "fuzzed.mcap"
    for _ in range(150):
        data = bytearray(source)
        pos = rnd.randrange(len(data))
        kind = rnd.randrange(3)
        if kind == 0:
            data[pos] ^= 1 << rnd.randrange(8)
        elif kind == 1:
            data[pos:pos + 8] = bytes(rnd.randrange(256) for _ in range(8))
        else:
            del data[pos:]
        path.write_bytes(bytes(data))
        try:
            rec = read_recording(path)
        except InputError as exc:
            assert "\n" not in str(exc) and str(exc).startswith(str(path))
            continue
        summarize(rec)
        if rec.problem:
            assert "\n" not in rec.problem


def test_the_cli_and_the_replay_answer_a_damaged_file_in_one_line(chunked: Path, tmp_path: Path) -> None:
    folder = tmp_path / "recordings"
    folder.mkdir()
    spared = damaged(chunked, folder / "spared.mcap", 2, "zstd-magic")
    lost = damaged(chunked, folder / "lost.mcap", 0, "zstd-magic")
    out = subprocess.run([sys.executable, "-m", "server.cli", "record", "summary", str(spared)],
                         capture_output=True, text=True, timeout=120, cwd=PROJECT_DIR)
    assert out.returncode == 0, out.stderr
    warnings = [line for line in out.stderr.splitlines() if line.startswith("teleprog: warning: ")]
    assert warnings == [line for line in out.stderr.splitlines() if "Traceback" not in line]
    assert len(warnings) == 1 and "spared.mcap: damaged recording: " in warnings[0]
    nothing = damaged(write_recording(tmp_path / "one.mcap", n=3), tmp_path / "nothing.mcap", 0, "zstd-magic")
    for argv in (["record", "summary", str(nothing)], ["replay", str(lost), "--port", "0"]):
        out = subprocess.run([sys.executable, "-m", "server.cli", *argv], capture_output=True, text=True, timeout=120,
                             cwd=PROJECT_DIR)
        assert out.returncode == 1
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("teleprog: error: ") and "damaged recording: " in lines[0], out.stderr
    app = create_replay_app(folder / "spared.mcap", folder=folder, build_page=False)
    with TestClient(app) as client:
        assert client.get("/api/replay").json()["problem"].startswith("spared.mcap: damaged recording: ")
        r = client.post("/api/replay/open", json={"name": "lost.mcap"})
        assert r.status_code == 400 and "lost.mcap: damaged recording: " in r.json()["detail"]
        assert client.get("/api/replay").json()["file"].endswith("spared.mcap")  # still up, on the same file
