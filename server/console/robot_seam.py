"""What the console needs of a robot client: the seam between the session and the link.

``server.robot_client.RobotClient`` satisfies :class:`RobotLink` over real WebSockets; tests hand
the session an in-memory fake of the same protocol. Callbacks (``on_report`` and friends) run on
the client's delivery thread, in arrival order, never on its asyncio loop (``server.delivery``):
they may take the session's lock without delaying a heartbeat. The coroutines are scheduled on
the loop by the session and never waited for from a page handler.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Protocol, runtime_checkable

from server.robot_client import ChannelHealth, RobotAccount
from shared.language.statements import Statement
from shared.wire.messages import RecoveryAck, StatusReport
from shared.wire.session import SessionRestart
from shared.wire.telemetry import TelemetryFrame


class ConnectedFlag(Protocol):
    def is_set(self) -> bool: ...


@runtime_checkable
class RobotLink(Protocol):
    """A robot's command and telemetry channels, as the console uses them."""

    url: str
    reconnects: int
    connected: ConnectedFlag

    def health(self) -> ChannelHealth: ...

    def on_report(self, listener: Callable[[StatusReport], None]) -> None: ...

    def on_telemetry(self, listener: Callable[[TelemetryFrame], None],
                     gate: Callable[[TelemetryFrame], bool] | None = None) -> None:
        """``listener(frame)`` on the delivery thread for each frame ``gate(frame)`` lets
        through (every frame without a gate). The gate runs where the frame arrives, before it
        is queued: it must not wait (see ``RobotClient.on_telemetry``)."""

    def on_restart(self, listener: Callable[[SessionRestart], None]) -> None: ...

    def on_account(self, listener: Callable[[RobotAccount], None]) -> None:
        """``listener(account)`` once: the robot's first welcome (what it holds and ran) and the reports since."""

    async def submit(self, statements: Iterable[Statement], timeout: float | None = None) -> tuple[int, ...]: ...

    async def stop(self, timeout: float | None = None) -> RecoveryAck: ...

    async def resume(self, timeout: float | None = None) -> RecoveryAck: ...

    async def skip(self, number: int, timeout: float | None = None) -> RecoveryAck: ...

    async def abort(self, timeout: float | None = None) -> RecoveryAck: ...
