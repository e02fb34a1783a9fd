"""The replay opens only what its folder holds, and no refusal hangs or leaks a file's bytes.

``POST /api/replay/open`` takes a name inside the replay's folder: ``..``, an absolute path
elsewhere and a symlink leading out are refused (400) without the file being read, a FIFO, a
folder or a device is refused without being opened (opening a FIFO would wait for a writer
forever), and no refusal quotes the bytes of the file it refused. The replay stays up after each.
``GET /api/sessions`` lists only what could be opened."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from server.recording import records
from server.recording.reader import list_recordings, read_recording
from server.recording.writer import RecordingWriter
from server.replay.app import create_replay_app
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.errors import InputError
from shared.files import name_in_folder, open_regular
from shared.paths import PROJECT_DIR

T0 = 1_800_000_000_000_000_000
SECRET = b"root:$6$SECRETSALT$do-not-echo-me:19000:0:99999:7:::\n"


def write_recording(path: Path, n: int = 20, chunk_size: int = 512 * 1024) -> Path:
    cell = load_cell(DEFAULT_CELL)
    w = RecordingWriter(path, chunk_size=chunk_size)
    w.start()
    cell_file = str(Path(DEFAULT_CELL).resolve().relative_to(PROJECT_DIR))
    w.put(records.SESSION, T0, records.SessionStart(cell=cell.name, cell_file=cell_file, robot=cell.robot.name,
                                                    dof=cell.robot.dof, started_at=T0 * 1e-9, delay_s=0.2))
    for i in range(n):
        w.put(records.VIRTUAL_ARM, T0 + i * 10_000_000,
              records.VirtualArm(q=[0.001 * i] * cell.robot.dof, world_T_tool=np.eye(4).tolist(), version=i + 1))
    w.close()
    return path


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    inside = tmp_path / "recordings"
    inside.mkdir()
    write_recording(inside / "good.mcap")
    (tmp_path / "shadow").write_bytes(SECRET)
    (tmp_path / "outside.mcap").write_bytes(SECRET)
    os.mkfifo(inside / "pipe.mcap")
    (inside / "leads-out.mcap").symlink_to(tmp_path / "shadow")
    (inside / "a-folder.mcap").mkdir()
    return inside


@pytest.fixture
def client(folder: Path):
    app = create_replay_app(folder / "good.mcap", folder=folder, build_page=False)
    with TestClient(app) as c:
        yield c


def _quotes_the_secret(text: str) -> bool:
    """Whether ``text`` gives away SECRET's bytes, as text or as the numbers of its first bytes."""
    return any(s in text for s in ("SECRETSALT", "do-not-echo", "root:$", "114, 111, 111, 116", "726f6f74"))


def _open(client: TestClient, name: str):
    """POST /api/replay/open on a thread, so that a request that hangs fails the test instead."""
    out: list = []
    t = threading.Thread(target=lambda: out.append(client.post("/api/replay/open", json={"name": name})), daemon=True)
    t.start()
    t.join(20)
    assert out, f"POST /api/replay/open {name!r} did not answer within 20 s"
    return out[0]


@pytest.mark.parametrize("name, says", [
    ("../outside.mcap", "outside the folder"),
    ("../shadow", "outside the folder"),
    ("leads-out.mcap", "outside the folder"),
    ("pipe.mcap", "FIFO"),
    ("a-folder.mcap", "a folder"),
    ("missing.mcap", "no recording 'missing.mcap'"),
    ("", "give the name"),
    ("bad\x00name.mcap", "NUL"),
])
def test_open_refuses_what_is_not_a_recording_of_the_folder(client: TestClient, folder: Path, name: str, says: str) -> None:
    r = _open(client, name)
    assert r.status_code == 400, r.text
    detail = r.json()["detail"]
    assert says in detail and "\n" not in detail
    assert not _quotes_the_secret(r.text)
    assert client.get("/api/replay").json()["file"].endswith("good.mcap")  # still up, still on the same file


def test_open_refuses_absolute_paths_outside_the_folder_without_quoting_them(client: TestClient, folder: Path) -> None:
    for path in (folder.parent / "shadow", folder.parent / "outside.mcap", Path("/etc/passwd"), Path("/etc/shadow")):
        r = _open(client, str(path))
        assert r.status_code == 400, r.text
        assert "outside the folder" in r.json()["detail"]
        assert not _quotes_the_secret(r.text) and "root:x:" not in r.text


def test_open_takes_names_and_paths_inside_the_folder(client: TestClient, folder: Path) -> None:
    write_recording(folder / "second.mcap", n=5)
    assert _open(client, "second.mcap").json()["file"].endswith("second.mcap")
    assert _open(client, str(folder / "good.mcap")).json()["file"].endswith("good.mcap")
    (folder / "sub").mkdir()
    write_recording(folder / "sub" / "third.mcap", n=3)
    assert _open(client, "sub/../sub/third.mcap").json()["file"].endswith("third.mcap")


def test_a_file_outside_the_folder_that_is_not_a_recording_is_refused_without_its_bytes(tmp_path: Path) -> None:
    """The command line's own file may be anywhere (it is given explicitly), but its refusal
    never echoes what it holds (before, the MCAP magic check quoted its first bytes)."""
    secret = tmp_path / "shadow"
    secret.write_bytes(SECRET)
    with pytest.raises(InputError) as exc:
        read_recording(secret)
    assert "not a session recording" in str(exc.value) and "MCAP's magic bytes" in str(exc.value)
    assert not _quotes_the_secret(str(exc.value))


def test_sessions_lists_only_what_can_be_opened(client: TestClient, folder: Path) -> None:
    names = [s["name"] for s in client.get("/api/sessions").json()["sessions"]]
    assert names == ["good.mcap"]
    assert [r.name for r in list_recordings(folder)] == ["good.mcap"]


def test_the_command_line_file_reopens_by_its_name_from_anywhere(tmp_path: Path, folder: Path) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    given = write_recording(elsewhere / "given.mcap", n=4)
    app = create_replay_app(given, folder=folder, build_page=False)
    with TestClient(app) as c:
        assert _open(c, "good.mcap").status_code == 200
        back = _open(c, "given.mcap")
        assert back.status_code == 200 and back.json()["file"] == str(given)
        assert _open(c, "../elsewhere/given.mcap").status_code == 400  # by its name only, not a path out


def test_special_files_are_refused_before_they_are_opened(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    for path, kind in ((fifo, "FIFO"), (tmp_path, "a folder"), (Path("/dev/null"), "character device")):
        with pytest.raises(InputError, match=kind):
            read_recording(path)
        with pytest.raises(InputError, match=kind):
            open_regular(path)


def test_name_in_folder_follows_symlinks_and_refuses_a_way_out(tmp_path: Path) -> None:
    inside = tmp_path / "in"
    inside.mkdir()
    (inside / "loop").symlink_to(inside / "loop")
    (inside / "up").symlink_to(tmp_path)
    assert name_in_folder(inside, "x.mcap") == (inside / "x.mcap").resolve()
    for name in ("../x.mcap", "up/x.mcap", str(tmp_path / "x.mcap"), "/x.mcap"):
        with pytest.raises(InputError, match="outside the folder"):
            name_in_folder(inside, name)
    with pytest.raises(InputError):
        name_in_folder(inside, "loop")  # a symlink loop: one line, whatever the Python version says


def test_teleprog_commands_refuse_a_fifo_in_one_line_and_do_not_wait(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    for argv in (["record", "summary", str(fifo)], ["replay", str(fifo), "--port", "0"]):
        out = subprocess.run([sys.executable, "-m", "server.cli", *argv], capture_output=True, text=True, timeout=60,
                             cwd=PROJECT_DIR)
        assert out.returncode == 1
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("teleprog: error: ") and "FIFO" in lines[0], out.stderr
