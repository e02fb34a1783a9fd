"""How the console's robot client takes answers a healthy run rarely shows.

A scripted robot (a real WebSocket server on loopback speaking the wire messages of
``shared.wire.messages``) answers the real ``RobotClient`` with what the telerobot sends when
things go wrong: ``BUFFER_FULL``, ``halted``, a refused recovery command, a message the console
cannot read. The client shows each in ``health()`` (and so in ``/api/link``) and its channel stays up.
"""

from __future__ import annotations

import asyncio

import pytest
from websockets.asyncio.server import serve

from server.robot_client import CommunicationRejected, RobotClient
from shared.language.statements import Event
from shared.wire.messages import (
    HaltCause,
    Halted,
    RecoveryAck,
    Rejected,
    RejectReason,
    Welcome,
    decode_message,
    encode_message,
)
from shared.wire.units import decode_unit
from support import free_port


class ScriptedRobot:
    """Answers hello with a welcome (then ``after_welcome``), every communication with
    ``answer(comm_id)`` and every recovery command with ``ack(cmd)``."""

    def __init__(self, *, halted: str | None = None) -> None:
        self.port = free_port()
        self.halted = halted
        self.after_welcome: list[str] = []
        self.ack_applied = True
        self.received: list[str] = []

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}"

    async def handle(self, ws) -> None:
        if ws.request.path != "/command":
            await ws.wait_closed()
            return
        async for raw in ws:
            if isinstance(raw, bytes):
                unit = decode_unit(raw)
                if unit.end:
                    await ws.send(encode_message(Rejected(
                        comm_id=unit.comm_id, reason=RejectReason.BUFFER_FULL, detail="the queue holds 5000 statements; limit 5000",
                    )))
                continue
            msg = decode_message(raw)
            self.received.append(msg.type)
            if msg.type == "hello":
                await ws.send(encode_message(Welcome(
                    session_id="scripted", last_answered_comm=0, units_held=0, last_applied_command=0, last_report_seq=0,
                    halted=self.halted,
                )))
                for text in self.after_welcome:
                    await ws.send(text)
            elif msg.type in ("stop", "resume", "skip", "abort"):
                detail = "resumed" if self.ack_applied else "nothing to resume"
                await ws.send(encode_message(RecoveryAck(command_id=msg.command_id, applied=self.ack_applied, detail=detail)))

    async def __aenter__(self) -> "ScriptedRobot":
        self._server = await serve(self.handle, "127.0.0.1", self.port)
        return self

    async def __aexit__(self, *exc: object) -> None:
        self._server.close()
        await self._server.wait_closed()


def test_buffer_full_reads_as_statements_held_back() -> None:
    async def run():
        async with ScriptedRobot() as robot, RobotClient(robot.url) as client:
            with pytest.raises(CommunicationRejected) as err:
                await client.submit([Event(name="a"), Event(name="b"), Event(name="c")], timeout=5)
            return str(err.value), client.health()

    message, health = asyncio.run(run())
    assert message.startswith("robot buffer full: 3 statements held back")
    assert "limit 5000" in message
    assert health.buffer_full and "limit 5000" in health.buffer_full
    assert health.connected and health.errors == 0


def test_halted_is_shown_until_a_resume_is_acknowledged() -> None:
    halted = Halted(cause=HaltCause.SILENCE, detail="nothing heard from the console for 1.2 s")

    async def run():
        async with ScriptedRobot() as robot, RobotClient(robot.url) as client:
            robot.after_welcome = [encode_message(halted)]
            await client.resume(timeout=5)  # an ack clears only a halt that came before it
            assert client.health().halted is None
            # the halt arrives on the next connection (after its welcome)
            client._ws.transport.abort()  # noqa: SLF001 - cut the socket: the client reconnects
            await asyncio.sleep(0.5)
            during = client.health()
            robot.ack_applied = False
            refused = await client.resume(timeout=5)
            still = client.health()
            robot.ack_applied = True
            await client.resume(timeout=5)
            return during, refused, still, client.health()

    during, refused, still, after = asyncio.run(run())
    assert during.halted == "silence: nothing heard from the console for 1.2 s"
    assert not refused.applied
    assert still.halted == during.halted  # a refused resume does not clear it
    assert still.refused == "resume #2 not applied: nothing to resume"
    assert after.halted is None


def test_welcome_halted_is_shown() -> None:
    async def run():
        async with ScriptedRobot(halted="silence: held since the console went quiet") as robot, RobotClient(robot.url) as client:
            return client.health()

    assert asyncio.run(run()).halted == "silence: held since the console went quiet"


def test_an_unreadable_message_is_counted_and_the_channel_stays_up() -> None:
    async def run():
        async with ScriptedRobot() as robot:
            robot.after_welcome = ['{"type": "status", "report_seq": 1, "number": 1, "state": "done", "robot": NaN}',
                                   '{"type": "hello", "type": "stop", "command_id": 1}']
            async with RobotClient(robot.url) as client:
                await asyncio.sleep(0.3)
                ack = await client.resume(timeout=5)
                return ack, client.health()

    ack, health = asyncio.run(run())
    assert ack.applied
    assert health.connected and health.command == "live"
    assert health.errors == 2 and "unreadable message from the robot" in health.last_error
