"""The real telerobot process behind the real link process, driven by the headless client.

One test runs in real time through the thesis's 3 s link (the peg transfer end to end); the
others use a short delay to keep the suite quick: killing and restarting the link mid-program
loses no statement and runs none twice, and stop overtakes a full buffer.
"""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest

from server.robot_client import RobotClient
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_program
from shared.language.statements import Move
from shared.paths import ASSETS_DIR
from shared.wire.messages import RobotState, StatementState
from support import ServerProcess, robot_headers

PEG_TRANSFER = parse_program((ASSETS_DIR / "programs" / "peg_transfer.tp").read_text()).statements
CELL = load_cell(DEFAULT_CELL)


@pytest.fixture
def robot(tmp_path):
    # a link killed and restarted is silent for seconds, past the limit that stops the arm (tested
    # in tests/safety): these tests are about exactly-once across the cut
    proc = ServerProcess(tmp_path, "robot", "--seed", "3", "--silence-limit-s", "30").start()
    yield proc
    proc.stop()


def test_peg_transfer_through_a_real_3_s_link(robot, tmp_path) -> None:
    link = ServerProcess(tmp_path, "link", "--robot", f"ws://127.0.0.1:{robot.port}", "--delay-ms", "3000").start()
    try:
        finals, elapsed, frame = asyncio.run(_peg_transfer(f"ws://127.0.0.1:{link.port}"))
    finally:
        link.stop()
    assert sorted(finals) == list(range(1, len(PEG_TRANSFER) + 1))
    assert all(r.state is StatementState.DONE for r in finals.values()), {n: r.reason for n, r in finals.items()}
    assert "seated in HOLE2" in finals[12].reason
    # the answer and the last report each crossed 3 s, plus the program's own motion
    assert elapsed > 6.0 + 15.0
    # telemetry arrives through the same link and shows the arm where the last report put it
    # (on physics the arm at rest still settles by some 1e-8 rad between the report and the frame)
    np.testing.assert_allclose(frame.q, finals[len(PEG_TRANSFER)].robot.q, atol=1e-5)
    assert robot.health()["numbered"] == len(PEG_TRANSFER)


async def _peg_transfer(url: str):
    async with RobotClient(url) as client:
        seen: set[tuple[str, str]] = set()

        async def sample() -> None:  # the delay is no silence: arrivals keep their spacing
            while True:
                h = client.health()
                # a robot without heartbeats is quiet between reports: judge only one that beats
                seen.add((h.command if client.heartbeats_heard else "live", h.telemetry))
                await asyncio.sleep(0.1)

        sampler = asyncio.create_task(sample())
        t0 = time.monotonic()
        numbers = await client.submit(PEG_TRANSFER, timeout=30)
        finals = await client.wait_final(numbers, timeout=120)
        elapsed = time.monotonic() - t0
        await asyncio.sleep(3.5)  # telemetry of the resting arm, one delay old
        sampler.cancel()
        assert {c for c, _ in seen} == {"live"} and {t for _, t in seen} <= {"live", "none"}, seen
        return finals, elapsed, client.telemetry


def test_killing_the_link_mid_program_loses_nothing_and_runs_nothing_twice(robot, tmp_path) -> None:
    link = ServerProcess(tmp_path, "link", "--robot", f"ws://127.0.0.1:{robot.port}", "--delay-ms", "300").start()
    try:
        finals, reconnects = asyncio.run(_kill_mid_program(link))
    finally:
        link.stop()
    assert sorted(finals) == list(range(1, len(PEG_TRANSFER) + 1))
    assert all(r.state is StatementState.DONE for r in finals.values()), {n: r.reason for n, r in finals.items()}
    assert reconnects >= 2
    health = robot.health()
    assert health["numbered"] == len(PEG_TRANSFER)  # every statement numbered (and so run) once


async def _kill_mid_program(link: ServerProcess):
    async with RobotClient(f"ws://127.0.0.1:{link.port}", reconnect_delay=0.1) as client:
        submitted = asyncio.create_task(client.submit(PEG_TRANSFER[:7], timeout=60))
        await asyncio.sleep(0.1)  # the units are inside the link
        link.kill()
        await asyncio.sleep(0.5)
        await asyncio.to_thread(link.start)
        first = await submitted
        await asyncio.sleep(4.0)  # mid-motion
        link.kill()
        rest = asyncio.create_task(client.submit(PEG_TRANSFER[7:], timeout=60))
        await asyncio.sleep(1.0)
        await asyncio.to_thread(link.start)
        second = await rest
        finals = await client.wait_final(first + second, timeout=120)
        # no report was delivered twice to the application
        finals_seen = [r.number for r in client.reports if r.state.final]
        assert len(finals_seen) == len(set(finals_seen))
        return finals, client.reconnects


def test_stop_overtakes_a_full_buffer_through_the_link(robot, tmp_path) -> None:
    link = ServerProcess(tmp_path, "link", "--robot", f"ws://127.0.0.1:{robot.port}", "--delay-ms", "200").start()
    try:
        state_after, queued, moved = asyncio.run(_stop_full_buffer(f"ws://127.0.0.1:{link.port}"))
    finally:
        link.stop()
    assert state_after is RobotState.STOPPED
    assert queued > 900
    assert moved < 1e-9


async def _stop_full_buffer(url: str):
    home = tuple(float(v) for v in CELL.q_home)
    away = tuple(float(v) for v in CELL.q_home + np.radians([25.0, 0, 0, 0, 0, 0]))
    program = [Move(joints=away if i % 2 == 0 else home) for i in range(1000)]
    async with RobotClient(url) as client:
        await client.submit(program, timeout=30)
        await asyncio.sleep(1.0)
        ack = await client.stop(timeout=10)
        assert ack.applied, ack.detail
        await asyncio.sleep(0.6)  # telemetry one delay behind
        q1 = np.array(client.telemetry.q)
        await asyncio.sleep(0.5)
        q2 = np.array(client.telemetry.q)
        state = client.telemetry.state
        queued = 1000 - len([r for r in client.reports if r.state.final])
        await client.abort(timeout=10)
        return state, queued, float(np.max(np.abs(q2 - q1)))


def test_malformed_traffic_is_rejected_and_the_robot_carries_on(robot) -> None:
    replies, health_before, health_after = asyncio.run(_garbage(robot))
    assert health_after == health_before  # nothing numbered, queued or moved
    assert replies and all(r.type == "rejected" for r in replies)
    assert {r.reason.value for r in replies} >= {"bad_json", "bad_message"}


async def _garbage(robot: ServerProcess):
    from websockets.asyncio.client import connect

    from shared.wire.messages import decode_message, encode_message
    from shared.wire.session import CommandSender
    from shared.wire.units import encode_unit

    health_before = robot.health()
    replies = []
    async with connect(f"ws://127.0.0.1:{robot.port}/command", additional_headers=robot_headers()) as ws:
        await ws.send(encode_message(CommandSender("fuzz").hello()))
        assert decode_message(await ws.recv()).type == "welcome"
        comm1 = encode_unit(1, 0, [Move(joints=(0.0,) * 6)], True)
        comm2 = encode_unit(2, 0, [Move(joints=(0.0,) * 6)], True)  # comm 1 is answered (rejected) by then
        for item in [b"\x00" * 7, comm1[:-3], comm2.replace(b'"MOVE"', b'"JUMP"'), b"TU" + b"\xff" * 40,
                     "{not json", '{"type": "explode"}', "[]", "x" * 100_000]:
            await ws.send(item)
            replies.append(decode_message(await asyncio.wait_for(ws.recv(), 5)))
    await asyncio.sleep(0.2)
    return replies, health_before, robot.health()
