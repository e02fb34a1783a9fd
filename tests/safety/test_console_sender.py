"""``CommandSender`` across a robot restart, sans I/O, against the real ``RobotCore`` receiver
of a first and then a second robot session (a restarted process starts with a new one)."""

from __future__ import annotations

from shared.language.statements import Event
from shared.wire.messages import Accepted, RecoveryAck, StatementState, Stop, Welcome, decode_message, encode_message
from shared.wire.session import CommandReceiver, CommandSender


def _greet(sender: CommandSender, receiver: CommandReceiver) -> tuple[Welcome, list]:
    step = receiver.on_text(encode_message(sender.hello()))
    welcome = step.replies[0]
    assert isinstance(welcome, Welcome)
    return welcome, step.replies[1:]


def _deliver(sender: CommandSender, receiver: CommandReceiver, units: list[bytes]) -> list:
    replies = [r for u in units for r in receiver.on_unit(u).replies]
    for r in replies:
        sender.on_message(r)
    return replies


def test_a_new_robot_session_leaves_the_old_work_unknown_and_numbers_from_one() -> None:
    sender = CommandSender("console")
    first = CommandReceiver("session-a")
    welcome, _ = _greet(sender, first)
    assert sender.on_welcome(welcome) == []
    assert sender.hello().session_id == "session-a"
    _, units = sender.submit([Event(name="a"), Event(name="b")])
    replies = _deliver(sender, first, units)
    assert any(isinstance(r, Accepted) and r.numbers == (1, 2) for r in replies)
    sender.on_message(first.report(1, StatementState.RUNNING))
    sender.submit([Event(name="c")])  # never reached the robot
    sender.command(Stop)

    second = CommandReceiver("session-b")  # the robot process restarted
    hello = sender.hello()
    assert hello.session_id == "session-a" and hello.last_answered_comm == 1
    welcome = decode_message(encode_message(second.on_text(encode_message(hello)).replies[0]))
    restart = sender.begin_session(welcome)
    assert restart is not None
    assert (restart.old_session, restart.new_session) == ("session-a", "session-b")
    assert restart.numbers == (1, 2) and restart.comms == (2,) and restart.commands == (1,)
    assert restart.describe() == (
        "robot restarted (session session-a -> session-b): the fate of statements 1-2; unanswered communications 2; "
        "unacknowledged commands 1 is unknown"
    )
    # nothing of the old session goes to the new robot; numbering starts again
    assert sender.on_welcome(welcome) == []
    assert sender.begin_session(welcome) is None  # the same session again is no restart
    assert not sender.outbox and sender.idle and sender.last_report_seq == 0
    comm, units = sender.submit([Event(name="d")])
    assert comm == 1
    replies = _deliver(sender, second, units)
    assert any(isinstance(r, Accepted) and r.numbers == (1,) for r in replies)
    cmd = sender.command(Stop)
    assert cmd.command_id == 1
    sender.on_message(RecoveryAck(command_id=1, applied=True))
    assert sender.idle


def test_a_socket_closing_under_a_submission_keeps_it_for_the_next_welcome() -> None:
    """The robot dies between the console's last look at the socket and its send: the submission
    neither fails nor is lost; it waits in the sender's outbox for the next welcome."""
    import asyncio

    import pytest
    from websockets.exceptions import ConnectionClosedError

    from server.robot_client import RobotClient

    class ClosedSocket:
        async def send(self, _data) -> None:
            raise ConnectionClosedError(None, None)

    async def run() -> RobotClient:
        client = RobotClient("ws://127.0.0.1:9")  # never started: the socket is the stand-in above
        client._ws = ClosedSocket()  # noqa: SLF001 - the moment between a socket's death and its notice
        client.connected.set()
        with pytest.raises(asyncio.TimeoutError):  # no answer yet; ConnectionClosed must not escape
            await client.submit([Event(name="kept")], timeout=0.2)
        return client

    client = asyncio.run(run())
    assert len(client.sender.outbox) == 1  # resent after the next welcome
