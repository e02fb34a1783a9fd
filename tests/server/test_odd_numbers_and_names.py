"""The console's API refuses numbers no session can mean and names outside its folders (issue 36):
a skip number of 10**23 is a 422, not a 200; a speed too slow to finish in a working day is
refused with its bound named, in the text form and the JSON form alike; ``GET /api/sessions``
lists only recordings that are regular files inside the recordings folder. The console answers
the next request after each."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.settings import ConsoleSettings


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("odd")
    recordings = root / "recordings"
    recordings.mkdir()
    os.mkfifo(recordings / "pipe.mcap")
    (root / "secret").write_text("not yours\n")
    (recordings / "leads-out.mcap").symlink_to(root / "secret")
    (recordings / "a-folder.mcap").mkdir()
    return recordings


@pytest.fixture(scope="module")
def client(folder: Path):
    app = create_app(ConsoleSettings(no_robot=True, record=False, record_dir=folder), build_page=False)
    with TestClient(app) as c:
        yield c


def _refused(response, status: int, *words: str) -> str:
    assert response.status_code == status, response.text
    detail = response.json()["detail"]
    assert "\n" not in detail and all(w in detail for w in words), detail
    return detail


@pytest.mark.parametrize("number", [10**23, 2**63, 10**6 + 1, 0, -1])
def test_a_skip_number_no_session_can_hold_is_a_422(client: TestClient, number: int) -> None:
    _refused(client.post("/api/robot/skip", json={"number": number}), 422, "number")
    assert client.get("/api/health").status_code == 200


def test_a_submit_range_no_program_can_hold_is_a_422(client: TestClient) -> None:
    _refused(client.post("/api/submit", json={"start": 0, "stop": 10**23}), 422, "stop")
    _refused(client.post("/api/submit", json={"start": 10**23, "stop": 1}), 422, "start")


@pytest.mark.parametrize("text, words", [
    ("DRAW TO (600, 0, 300) mm WITH SPEED 1e-300 mm/s", ("slowest speed bound", "0.1 mm/s")),
    ("SPEED 0.0001 %", ("slowest speed bound", "0.1 %")),
    ("DRIVE J1 TO 10 deg WITH SPEED 0.001 deg/s", ("slowest speed bound", "0.1 deg/s")),
])
def test_a_speed_too_slow_for_a_working_day_is_refused_in_the_text_form(client: TestClient, text: str, words) -> None:
    _refused(client.post("/api/program/load", json={"text": text + "\n", "filename": "slow.tp"}), 400, *words)
    assert client.get("/api/program").status_code == 200


def test_a_speed_too_slow_for_a_working_day_is_refused_in_the_json_form(client: TestClient) -> None:
    statement = {"kind": "DRIVE", "joint": 1, "target": 0.5, "speed": {"value": 5e-324, "unit": "rad/s"}}
    _refused(client.post("/api/program/insert", json={"statement": statement}), 422, "slowest speed bound")
    _refused(client.post("/api/program/conditions", json={"speed": {"value": 1e-300, "unit": "m/s"}}), 422,
             "slowest speed bound")
    _refused(client.post("/api/program/load", json={"text": json.dumps([statement]),
                                                    "filename": "slow.json"}), 400, "slowest speed bound")


def test_sessions_lists_only_regular_files_inside_the_folder(client: TestClient, folder: Path) -> None:
    listed = client.get("/api/sessions").json()
    assert listed["folder"] == str(folder) and listed["sessions"] == []


def test_a_program_files_name_is_a_label_never_a_path_that_is_opened(client: TestClient) -> None:
    for name in ("/etc/passwd", "../../etc/shadow", "pipe.mcap"):
        loaded = client.post("/api/program/load", json={"text": "SPEED 50 %\n", "filename": name})
        assert loaded.status_code == 200, loaded.text
        assert [e["text"] for e in loaded.json()["entries"] if e["text"]] == ["SPEED 50 %"]
