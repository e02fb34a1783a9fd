"""``teleprog link`` as a real process on loopback, between real WebSockets.

The delay is asserted as a behaviour, both ways: no message arrives before the set delay, and the
median delay error is under 50 ms (loose enough for a loaded test machine; how closely the relay
holds the delay, its p50/p99, is measured in ``benchmarks/bench_link.py``, not here). Order,
exactly-once execution across a killed and restarted link, clean closing when the robot goes away,
and faults are checked with the stand-in robot of ``link_standin``.
"""

from __future__ import annotations

import asyncio
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidStatus

from link_standin import CommandClient, LinkProcess, StandInRobot
from shared.language.statements import Drive
from shared.wire.messages import Welcome, decode_message, encode_message
from shared.wire.session import CommandSender
from shared.wire.telemetry import decode_frame
from support import PROJECT_DIR

STAMP = struct.Struct("<Id")  # sequence number, time.perf_counter() at sending


def _program(n: int, base: int) -> list:
    return [Drive(joint=1 + (base + i) % 6, target=(base + i) * 1e-4) for i in range(n)]


def test_delay_is_accurate_and_order_kept_both_ways(tmp_path):
    delay = 0.31  # not a whole number of 20 ms periods: arrivals fall between the test's own sends
    up_err, down_err, up_seq, down_frames, health = asyncio.run(_delay_run(tmp_path, delay))
    assert up_seq == list(range(len(up_seq))) and len(up_seq) == 150  # all arrived, in order
    assert down_frames == list(range(down_frames[0], down_frames[0] + len(down_frames)))
    assert len(down_frames) > 100
    for name, err in (("up", up_err), ("down", down_err)):
        assert err.min() >= 0.0, "a message arrived before the set delay"
        # the delay is the set one, not some other: half the messages within 50 ms of it even
        # on a loaded machine (how close it holds is measured in benchmarks/bench_link.py)
        assert np.median(err) < 0.050, (
            f"{name}: median delay error {np.median(err) * 1e3:.2f} ms; worst {np.sort(err)[-5:] * 1e3} ms; "
            f"relay's own lateness {health['lateness_ms']}")


async def _delay_run(tmp_path, delay: float):
    robot = StandInRobot(telemetry_hz=50.0)
    await robot.start()
    link = await asyncio.to_thread(LinkProcess(robot.port, tmp_path, "--delay-ms", str(delay * 1e3)).start)
    try:
        down: list[tuple[float, bytes]] = []
        async with connect(link.url + "/telemetry", compression=None) as ws:

            async def read() -> None:
                async for raw in ws:
                    down.append((time.perf_counter(), raw))

            reader = asyncio.create_task(read())
            t0 = time.perf_counter()
            for k in range(150):  # 3 s of 50 Hz commands up while telemetry flows down
                await ws.send(STAMP.pack(k, time.perf_counter()))
                await asyncio.sleep(max(0.0, t0 + (k + 1) / 50 - time.perf_counter()))
            await asyncio.sleep(delay + 0.2)
            reader.cancel()
        ups = [(a.at, *STAMP.unpack(a.payload)) for a in robot.arrivals if a.path == "/telemetry"]
        up_err = np.array([at - sent - delay for at, _, sent in ups[5:]])  # after the connection warmed up
        frames = [(at, decode_frame(raw)) for at, raw in down]
        frames = [(at, f) for at, f in frames if f.time > t0 + 0.05]  # steady state, not the handshake
        down_err = np.array([at - f.time - delay for at, f in frames])
        health = await asyncio.to_thread(link.health)
        return up_err, down_err, [k for _, k, _ in ups], [f.frame for _, f in frames], health
    finally:
        await asyncio.to_thread(link.stop)
        await robot.close()


def test_jitter_never_reorders_through_the_process(tmp_path):
    received, floor_ok = asyncio.run(_jitter_run(tmp_path))
    assert received == list(range(400))
    assert floor_ok


async def _jitter_run(tmp_path):
    robot = StandInRobot()
    await robot.start()
    link = await asyncio.to_thread(
        LinkProcess(robot.port, tmp_path, "--delay-ms", "100", "--jitter-ms", "40", "--seed", "7").start
    )
    try:
        async with connect(link.url + "/telemetry", compression=None) as ws:
            for k in range(400):  # back to back: jitter draws far larger than the spacing
                await ws.send(STAMP.pack(k, time.perf_counter()))
            for _ in range(100):
                if sum(a.path == "/telemetry" for a in robot.arrivals) == 400:
                    break
                await asyncio.sleep(0.02)
        ups = [(a.at, *STAMP.unpack(a.payload)) for a in robot.arrivals if a.path == "/telemetry"]
        return [k for _, k, _ in ups], all(at - sent >= 0.1 for at, _, sent in ups)
    finally:
        await asyncio.to_thread(link.stop)
        await robot.close()


def test_killing_the_link_mid_program_loses_nothing_and_runs_nothing_twice(tmp_path):
    robot, client, kills = asyncio.run(_kill_run(tmp_path, comms=8, per_comm=50))
    n = 8 * 50
    expected = [s for k in range(8) for s in _program(50, 1000 * k)]
    assert [s for _, s in robot.buffered] == expected  # every statement buffered once, in order
    assert [num for num, _ in robot.buffered] == list(range(1, n + 1))
    for num in range(1, n + 1):
        finals = [s for s in client.sender.statuses[num] if s.final]
        assert [f.value for f in finals] == ["done"], (num, client.sender.statuses[num])
    # the kills fell mid-program, with a communication still unanswered (in flight in the link)
    assert len(kills) == 2 and all(buffered < n and unanswered >= 1 for buffered, unanswered in kills), kills
    assert client.connects >= 3


async def _kill_run(tmp_path, comms: int, per_comm: int):
    robot = StandInRobot(step_s=0.002)
    await robot.start()
    link = await asyncio.to_thread(LinkProcess(robot.port, tmp_path, "--delay-ms", "100").start)
    client = CommandClient(link.url, per_unit=20)
    kills: list[tuple[int, int]] = []

    async def driver() -> None:
        for k in range(comms):
            while not client.welcomed:
                await asyncio.sleep(0.005)
            await client.submit(_program(per_comm, 1000 * k))
            if k in (2, 5):
                await asyncio.sleep(0.03)  # its units are inside the link now (100 ms delay)
                kills.append((len(robot.buffered), len(client.sender.outbox)))
                link.kill()
                await asyncio.sleep(0.2)
                await asyncio.to_thread(link.start)
            else:
                await asyncio.sleep(0.15)

    try:
        await asyncio.gather(client.run(comms * per_comm, timeout=60), driver())
        return robot, client, kills
    finally:
        await asyncio.to_thread(link.stop)
        await robot.close()


def test_robot_loss_closes_the_console_side_cleanly_and_the_link_recovers(tmp_path):
    result = asyncio.run(_robot_loss_run(tmp_path))
    assert result["close"] == (1011, "robot connection lost")
    assert result["unreachable_close"] == (1011, "robot unreachable")
    assert result["health"]["robot_losses"] == 1 and result["health"]["robot_unreachable"] == 1
    assert result["link_alive"]
    assert result["welcome_after_restart"]


async def _robot_loss_run(tmp_path):
    robot = StandInRobot()
    await robot.start()
    link = await asyncio.to_thread(LinkProcess(robot.port, tmp_path, "--delay-ms", "50").start)
    out: dict = {}
    sender = CommandSender("console-loss")
    try:
        async with connect(link.url + "/command", compression=None) as ws:
            await ws.send(encode_message(sender.hello()))
            assert isinstance(decode_message(await ws.recv()), Welcome)
            await robot.stop()  # the robot process goes away
            with pytest.raises(ConnectionClosed):
                await asyncio.wait_for(ws.recv(), 5)
            out["close"] = (ws.close_code, ws.close_reason)
        async with connect(link.url + "/command", compression=None) as ws:  # robot still down
            with pytest.raises(ConnectionClosed):
                await asyncio.wait_for(ws.recv(), 5)
            out["unreachable_close"] = (ws.close_code, ws.close_reason)
        out["health"] = await asyncio.to_thread(link.health)
        out["link_alive"] = link.proc.poll() is None
        await robot.start()  # the robot is back on the same port
        async with connect(link.url + "/command", compression=None) as ws:
            await ws.send(encode_message(sender.hello()))
            out["welcome_after_restart"] = isinstance(decode_message(await asyncio.wait_for(ws.recv(), 5)), Welcome)
        return out
    finally:
        await asyncio.to_thread(link.stop)
        await robot.close()


def test_faults_cut_the_connection_refuse_reconnects_and_the_protocol_recovers(tmp_path):
    robot, client, health = asyncio.run(_fault_run(tmp_path))
    assert health["faults"] >= 1
    assert (1011, "link fault") in client.closes
    assert [num for num, _ in robot.buffered] == list(range(1, 301))
    assert [s for _, s in robot.buffered] == [s for k in range(6) for s in _program(50, 1000 * k)]
    assert all(client.sender.final_state(n) is not None for n in range(1, 301))


async def _fault_run(tmp_path):
    robot = StandInRobot(step_s=0.001)
    await robot.start()
    link = await asyncio.to_thread(
        LinkProcess(robot.port, tmp_path, "--delay-ms", "20", "--drop-probability", "0.004", "--outage-ms", "150",
                    "--seed", "3").start
    )
    client = CommandClient(link.url, per_unit=10)
    try:
        for k in range(6):
            client.sender.submit(_program(50, 1000 * k))
        await client.run(300, timeout=60)
        return robot, client, await asyncio.to_thread(link.health)
    finally:
        await asyncio.to_thread(link.stop)
        await robot.close()


def test_a_fault_breaks_every_channel_and_refuses_reconnects_during_the_outage(tmp_path):
    closes, status = asyncio.run(_outage_run(tmp_path))
    assert closes == [(1011, "link fault"), (1011, "link fault")]
    assert status == 503


async def _outage_run(tmp_path):
    robot = StandInRobot()
    await robot.start()
    link = await asyncio.to_thread(
        LinkProcess(robot.port, tmp_path, "--delay-ms", "10", "--drop-probability", "0.999", "--outage-ms", "5000").start
    )
    try:
        async with connect(link.url + "/telemetry", compression=None) as tel, \
                connect(link.url + "/command", compression=None) as cmd:
            await asyncio.sleep(0.1)  # both joined to the robot
            await cmd.send(b"lost")  # lost on the command channel: the whole line goes down
            for ws in (cmd, tel):
                with pytest.raises(ConnectionClosed):
                    await asyncio.wait_for(ws.recv(), 5)
            closes = [(ws.close_code, ws.close_reason) for ws in (cmd, tel)]
        with pytest.raises(InvalidStatus) as info:
            async with connect(link.url + "/telemetry", compression=None):
                pass
        return closes, info.value.response.status_code
    finally:
        await asyncio.to_thread(link.stop)
        await robot.close()


def test_unknown_path_is_refused_and_health_answers(tmp_path):
    async def run():
        robot = StandInRobot()
        await robot.start()
        link = await asyncio.to_thread(LinkProcess(robot.port, tmp_path, "--delay-ms", "1").start)
        try:
            with pytest.raises(InvalidStatus) as info:
                async with connect(link.url + "/video"):
                    pass
            return info.value.response.status_code, await asyncio.to_thread(link.health), await asyncio.to_thread(link.stop)
        finally:
            await asyncio.to_thread(link.stop)
            await robot.close()

    status, health, rc = asyncio.run(run())
    assert status == 404
    assert health["ok"] and health["delay_s"] == pytest.approx(0.001) and health["open"] == 0
    assert rc == 0  # SIGTERM ends the process cleanly


@pytest.mark.parametrize(
    ("flags", "needle"),
    [(["--delay-ms", "-1"], "delay_s"), (["--robot", "http://x"], "ws://"), (["--drop-probability", "1"], "drop_probability")],
)
def test_bad_flags_exit_1_with_one_line(flags, needle):
    proc = subprocess.run([sys.executable, "-m", "server.cli", "link", *flags], cwd=PROJECT_DIR,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert needle in proc.stderr and "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_environment_sets_the_delay(tmp_path, monkeypatch):
    monkeypatch.setenv("TELEPROG_LINK_DELAY_S", "0.25")
    from server.relay.link_relay import LinkSettings

    assert LinkSettings.load().delay_s == 0.25
    assert LinkSettings.load(delay_s=0.5).delay_s == 0.5  # a flag overrides the environment


def test_a_failing_timer_closes_the_pipe_instead_of_hanging(monkeypatch):
    """In-process relay whose core fails on poll: both ends get 1011 'link error', nothing hangs."""
    from server.relay.link_relay import LinkRelay, LinkSettings
    from shared.link.core import LinkCore

    calls = {"n": 0}
    real_poll = LinkCore.poll

    def failing_poll(self, now):
        calls["n"] += 1
        if self.in_flight():
            raise RuntimeError("injected")
        return real_poll(self, now)

    monkeypatch.setattr(LinkCore, "poll", failing_poll)

    async def run():
        robot = StandInRobot()
        await robot.start()
        relay = LinkRelay(LinkSettings.load(port=0, robot=f"ws://127.0.0.1:{robot.port}", delay_s=0.01))
        await relay.start()
        try:
            async with connect(f"ws://127.0.0.1:{relay.port}/telemetry", compression=None) as ws:
                await ws.send(b"x")
                with pytest.raises(ConnectionClosed):
                    await asyncio.wait_for(ws.recv(), 5)
                code = (ws.close_code, ws.close_reason)
            await asyncio.wait_for(relay.stop(), 5)  # no handler left waiting
            return code, relay.stats.open
        finally:
            await robot.close()

    (code, open_pipes) = asyncio.run(run())
    assert code == (1011, "link error")
    assert open_pipes == 0 and calls["n"] >= 1
