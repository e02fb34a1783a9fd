"""The console's robot client survives what its own handlers do and a robot restart.

Real ``teleprog robot`` processes, the real ``RobotClient`` over loopback WebSockets:

* a report listener and a telemetry listener that raise (as ``Session.on_report`` once did on a
  statement it could not write) leave both channels up: the error is counted and kept, and later
  submissions are still answered and tracked to their final status;
* listeners that take longer than the robot's silence limit (as the task monitor's play of a
  submitted range once did under a lock every telemetry frame waits on) do not silence the
  console: heartbeats go on, the robot never halts itself, and STOP is acknowledged at once;
* the robot killed and started again on the same port while statements are queued: the client
  reconnects to the new session, everything of the old one fails with ``RobotRestarted`` (its
  fate is unknown), nothing of it is sent to the new robot, and a new submission runs.
"""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from server.robot_client import RobotClient, RobotRestarted
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.statements import Event, Move, SetSpeed, Speed, SpeedUnit
from shared.wire.messages import StatementState
from support import ServerProcess, wait_for

CELL = load_cell(DEFAULT_CELL)


def _quick(n: int) -> list:
    return [Event(name=f"e{i}") for i in range(n)]


def _slow(n: int) -> list:
    """Joint moves back and forth at low speed: seconds of queued work."""
    home = tuple(float(v) for v in CELL.q_home)
    away = tuple(float(v) for v in CELL.q_home + np.radians([20.0, 0, 0, 0, 0, 0]))
    return [SetSpeed(speed=Speed(value=0.1, unit=SpeedUnit.FRACTION))] + [Move(joints=away if i % 2 == 0 else home) for i in range(n)]


@pytest.fixture
def robot(tmp_path):
    proc = ServerProcess(tmp_path, "robot").start()
    yield proc
    proc.stop()


def test_raising_listeners_leave_the_channels_up_and_later_submissions_tracked(robot) -> None:
    async def run():
        async with RobotClient(robot.url) as client:
            seen: list[int] = []

            def bad_report(report) -> None:
                seen.append(report.number)
                raise ValueError(f"cannot write statement {report.number}")

            def bad_frame(frame) -> None:
                raise OverflowError("odd telemetry value")

            client.on_report(bad_report)
            client.on_telemetry(bad_frame)
            first = await client.submit(_quick(3), timeout=10)
            finals = await client.wait_final(first, timeout=20)
            await asyncio.sleep(0.3)  # telemetry frames, each raising in its listener
            second = await client.submit(_quick(2), timeout=10)
            finals2 = await client.wait_final(second, timeout=20)
            return client.reconnects, first, finals, second, finals2, seen, client.health()

    reconnects, first, finals, second, finals2, seen, health = asyncio.run(run())
    assert all(r.state is StatementState.DONE for r in {**finals, **finals2}.values())
    assert second == (first[-1] + 1, first[-1] + 2)
    assert set(second) <= set(seen)  # the listener kept being called for later reports
    assert health.connected and health.command == "live" and reconnects == 0
    assert health.errors >= len(seen) + 1
    assert "ValueError" in (health.last_error or "") or "OverflowError" in (health.last_error or "")


def test_slow_listeners_never_silence_the_console_or_hold_up_stop(robot) -> None:
    import threading
    import time

    busy = threading.Lock()  # a session lock a page request holds for seconds

    async def run():
        async with RobotClient(robot.url) as client:
            frames: list[float] = []

            def slow_report(report) -> None:
                with busy:
                    time.sleep(0.5)

            def slow_frame(frame) -> None:
                with busy:
                    frames.append(time.monotonic())

            client.on_report(slow_report)
            client.on_telemetry(slow_frame)
            numbers = await client.submit(_slow(4), timeout=10)
            heard = client.heartbeats_heard
            await asyncio.to_thread(busy.acquire)  # 3 s with every listener stuck behind it
            try:
                await asyncio.sleep(3.0)
                t0 = time.monotonic()
                ack = await client.stop(timeout=5)
                stop_s = time.monotonic() - t0
                halted = client.halted
                health = client.health()
            finally:
                busy.release()
            await client.abort(timeout=5)
            await client.wait_final(numbers, timeout=20)
            # the listeners run in arrival order, so the frames queued behind the reports of the
            # 3 s (0.5 s each) come after them: wait for one before the client closes its queue
            await asyncio.to_thread(wait_for, lambda: frames, 10.0, 0.05, "a telemetry frame delivered after the lock")
            return ack, stop_s, halted, health, client.heartbeats_heard - heard, frames

    ack, stop_s, halted, health, heartbeats, frames = asyncio.run(run())
    assert halted is None, f"the robot halted itself while the listeners were busy: {halted}"
    assert ack.applied and stop_s < 1.0, (ack, stop_s)  # STOP went out and came back at once
    assert health.command == "live" and health.connected
    assert heartbeats >= 10  # the robot's heartbeats kept arriving (0.2 s apart) through the 3 s
    assert frames  # telemetry reached its listener again once the lock was free


def test_robot_restart_fails_the_old_session_and_a_new_submission_runs(robot, tmp_path) -> None:
    async def run():
        async with RobotClient(robot.url, reconnect_delay=0.1) as client:
            old_session = client.sender.session_id
            numbers = await client.submit(_slow(6), timeout=10)
            old_finals = asyncio.create_task(client.wait_final(numbers, timeout=60))
            await asyncio.sleep(0.5)  # the first move is running, the rest queued
            await asyncio.to_thread(robot.kill)
            queued = asyncio.create_task(client.submit(_quick(2), timeout=60))  # while the robot is down
            await asyncio.sleep(0.3)
            await asyncio.to_thread(robot.start)
            with pytest.raises(RobotRestarted) as old_error:
                await old_finals
            with pytest.raises(RobotRestarted):
                await queued
            fresh = await client.submit(_quick(2), timeout=20)
            fresh_finals = await client.wait_final(fresh, timeout=20)
            return client, old_session, numbers, str(old_error.value), fresh, fresh_finals

    client, old_session, numbers, message, fresh, fresh_finals = asyncio.run(run())
    new_session = client.sender.session_id
    assert new_session != old_session
    assert f"robot restarted (session {old_session} -> {new_session})" in message and "unknown" in message
    assert client.restarts and set(numbers[1:]) <= set(client.restarts[0].numbers)
    # numbering starts again at 1 on the new robot, and nothing of the old session reached it
    assert fresh == (1, 2)
    assert all(r.state is StatementState.DONE for r in fresh_finals.values())
    assert robot.health()["numbered"] == 2
    assert client.health().restarts == 1
