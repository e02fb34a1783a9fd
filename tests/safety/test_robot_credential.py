"""The robot's door (issue 36): its command and telemetry channels answer only to a client that
presents its credential, straight, through the link, or through a console; the console and the
robot ``teleprog up`` starts, and a robot started alone with a credential given, work as before.
Real processes on loopback."""

from __future__ import annotations

import asyncio
import json
import os
import secrets
import stat
import subprocess
import sys

import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from server.robot_client import RobotClient
from shared.language.statements import Move
from shared.wire.credential import ENV_VAR, headers
from shared.wire.messages import Hello, encode_message
from support import PROJECT_DIR, ServerProcess, child_env, free_port, start_console, stop_process, wait_for

SECRET = "robot-alone-" + secrets.token_urlsafe(16)
NO_CREDENTIAL = {ENV_VAR: None}  # a child that is given none


def _refusal(url: str, credential: str | None) -> tuple[int, str]:
    """The HTTP status and first line with which ``url`` refuses an upgrade presenting ``credential``."""
    with pytest.raises(InvalidStatus) as refused:
        with connect(url, additional_headers=headers(credential), open_timeout=10):
            pass
    response = refused.value.response
    return response.status_code, bytes(response.body).decode().strip()


def _closed_by_the_link(url: str, credential: str | None) -> tuple[int, str]:
    """The close code and reason of a link connection whose robot refuses the credential."""
    with connect(url, additional_headers=headers(credential), open_timeout=10) as ws:
        with pytest.raises(ConnectionClosed) as closed:  # the close may come before the hello leaves
            ws.send(encode_message(Hello(client_id="intruder")))
            while True:
                ws.recv(timeout=30)
    return closed.value.rcvd.code, closed.value.rcvd.reason


@pytest.fixture(scope="module")
def robot_alone(tmp_path_factory):
    """A robot started on its own with a credential file (its user's alone), and a link to it."""
    tmp = tmp_path_factory.mktemp("door")
    secret_file = tmp / "robot.credential"
    secret_file.write_text(SECRET + "\n")
    secret_file.chmod(0o600)
    robot = ServerProcess(tmp, "robot", "--credential-file", str(secret_file), env=NO_CREDENTIAL).start()
    link = ServerProcess(tmp, "link", "--robot", robot.url, "--delay-ms", "100", env=NO_CREDENTIAL).start()
    yield robot, link, secret_file
    link.stop()
    robot.stop()


def test_no_client_without_the_credential_reaches_the_robot_straight_or_through_the_link(robot_alone) -> None:
    robot, link, _ = robot_alone
    for channel in ("/command", "/telemetry"):
        status, reason = _refusal(robot.url + channel, None)
        assert status == 401 and reason.startswith("no credential: the robot answers only to its console")
        status, reason = _refusal(robot.url + channel, os.environ[ENV_VAR])  # the tests' credential is another
        assert (status, reason) == (401, "wrong credential: the robot answers only to its console")
    code, reason = _closed_by_the_link(link.url + "/command", None)
    assert code == 1008 and reason.startswith("robot refused: no credential")
    code, reason = _closed_by_the_link(link.url + "/command", "x" * 32)
    assert code == 1008 and reason == "robot refused: wrong credential: the robot answers only to its console"
    health = robot.health()
    assert health["numbered"] == 0 and health["refused"] >= 6  # nothing moved; every try counted
    assert SECRET not in robot.log_path.read_text() and SECRET not in link.log_path.read_text()


def test_a_client_given_the_credential_drives_the_robot_started_alone(robot_alone) -> None:
    robot, link, _ = robot_alone
    before = robot.health()["numbered"]

    async def drive() -> str:
        async with RobotClient(link.url, credential=SECRET) as client:
            numbers = await client.submit([Move(joints=(0.0, -0.2, 0.2, 0.0, 0.3, 0.0))], timeout=30)
            finals = await client.wait_final(numbers, timeout=60)
            return finals[numbers[0]].state.value

    assert asyncio.run(drive()) == "done"
    assert robot.health()["numbered"] == before + 1


def test_a_console_without_the_credential_cannot_move_the_robot_and_says_why(robot_alone, tmp_path) -> None:
    robot, link, secret_file = robot_alone
    before = robot.health()["numbered"]
    stranger = start_console(tmp_path, "--robot-url", link.url, "--no-record", name="stranger", env=NO_CREDENTIAL)
    try:
        link_view = wait_for(lambda: (v := stranger.api("GET", "/api/link").json())["door"] and v, timeout=60,
                             what="the console showing the robot's refusal")
        assert link_view["door"].startswith("robot refused: no credential") and not link_view["connected"]
        assert any(p.startswith("the robot refuses this console") for p in link_view["problems"])
        stranger.call("PUT", "/api/regime", {"regime": "free"})
        stranger.call("POST", "/api/program/insert", {"text": "DRIVE J1 TO 5 deg"})
        stranger.api("POST", "/api/submit", json={"start": 0, "stop": 1})
    finally:
        stop_process(stranger.proc)
    assert robot.health()["numbered"] == before  # the submission never reached the robot

    trusted = start_console(tmp_path, "--robot-url", link.url, "--no-record", "--robot-credential-file", str(secret_file),
                            name="trusted", env=NO_CREDENTIAL)
    try:
        wait_for(lambda: trusted.api("GET", "/api/link").json()["status"] == "live", timeout=60, what="a live link")
        trusted.call("PUT", "/api/regime", {"regime": "free"})  # one statement, sent without a preview
        trusted.call("POST", "/api/program/insert", {"text": "DRIVE J1 TO 5 deg"})
        trusted.call("POST", "/api/submit", {"start": 0, "stop": 1})
        wait_for(lambda: [i["status"] for i in trusted.call("GET", "/api/sent")["items"]] == ["done"], timeout=60,
                 what="the statement done")
        assert robot.health()["numbered"] == before + 1
        assert SECRET not in trusted.log_path.read_text()
    finally:
        stop_process(trusted.proc)


def test_the_robot_teleprog_up_starts_answers_to_that_console_alone(tmp_path) -> None:
    robot_port = str(free_port())
    up = start_console(tmp_path, "--delay-ms", "100", "--robot-port", robot_port, "--no-record", env=NO_CREDENTIAL)
    try:
        wait_for(lambda: up.api("GET", "/api/link").json()["status"] == "live", timeout=90, what="a live link")
        for credential in (None, os.environ[ENV_VAR]):
            status, _ = _refusal(f"ws://127.0.0.1:{robot_port}/command", credential)
            assert status == 401
        up.call("PUT", "/api/regime", {"regime": "free"})
        up.call("POST", "/api/program/insert", {"text": "DRIVE J1 TO 5 deg"})
        up.call("POST", "/api/submit", {"start": 0, "stop": 1})
        wait_for(lambda: [i["status"] for i in up.call("GET", "/api/sent")["items"]] == ["done"], timeout=60,
                 what="the statement done")
        link = up.api("GET", "/api/link").json()
        assert link["url"] is None and "credential" not in json.dumps(link).lower()
    finally:
        stop_process(up.proc)


def test_a_robot_given_no_credential_makes_one_only_its_user_can_read(tmp_path) -> None:
    state = tmp_path / "state"
    robot = ServerProcess(tmp_path, "robot", env={ENV_VAR: None, "XDG_STATE_HOME": str(state)}).start()
    try:
        made = state / "teleprog" / f"robot-{robot.port}.credential"
        assert stat.S_IMODE(made.stat().st_mode) == 0o600
        secret = made.read_text().strip()
        assert secret not in robot.log_path.read_text() and str(made) in robot.log_path.read_text()
        with connect(robot.url + "/command", additional_headers=headers(secret), open_timeout=10) as ws:
            ws.send(encode_message(Hello(client_id="owner")))
            assert json.loads(ws.recv(timeout=30))["type"] == "welcome"
        assert _refusal(robot.url + "/command", None)[0] == 401
    finally:
        robot.stop()


@pytest.mark.parametrize("mode, says", [(0o644, "readable or writable by others"), (0o600, "characters")])
def test_a_bad_credential_file_is_one_line_before_anything_listens(tmp_path, mode: int, says: str) -> None:
    secret_file = tmp_path / "credential"
    secret_file.write_text(SECRET if mode != 0o600 else "short")
    secret_file.chmod(mode)
    proc = subprocess.run(
        [sys.executable, "-m", "server.cli", "robot", "--port", "0", "--credential-file", str(secret_file)],
        capture_output=True, text=True, timeout=120, cwd=PROJECT_DIR, env=child_env(NO_CREDENTIAL),
    )
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode != 0 and len(lines) == 1 and says in lines[0] and str(secret_file) in lines[0]
    assert SECRET not in proc.stderr and "Traceback" not in proc.stderr


def test_no_log_line_shows_a_credential_even_at_debug_level() -> None:
    """websockets logs a handshake's headers at debug level (``teleprog -v``): the CLI's handlers hide the credential."""
    import logging

    from server.cli import _HideCredentials

    record = logging.LogRecord("websockets.server", logging.DEBUG, __file__, 1, "< %s: %s", ("Authorization", f"Bearer {SECRET}"), None)
    assert _HideCredentials().filter(record) and record.getMessage() == "< Authorization: Bearer [hidden]"
