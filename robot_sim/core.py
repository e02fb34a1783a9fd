"""The telerobot without sockets or clocks: the command receiver wired to the executor.

``RobotCore`` takes what arrives on the command channel (text messages and binary units), feeds
accepted statements to the executor's buffer, applies recovery commands, and turns every status
change of the executor into a numbered status report. ``tick()`` advances the executor by one
servo period. The asyncio service (``robot_sim.service``) calls these from its socket handlers and
its servo loop; tests call them directly in virtual time.

A lost console connection leaves the robot safe and reported: the statement in progress runs to
its end (the operator planned it with the delay in mind), nothing new starts until a console is
back, and the state in telemetry reads DISCONNECTED meanwhile.
"""

from __future__ import annotations

import logging
import uuid

from pydantic import BaseModel

from robot_sim.executor import Executor
from shared.wire.messages import AbortFlush, Resume, RobotState, SkipCurrent, StatementState, Stop, Welcome
from shared.wire.session import CommandReceiver, ReceiverStep
from shared.wire.telemetry import TelemetryFrame, encode_frame

log = logging.getLogger(__name__)


class RobotCore:
    """One robot: receiver (numbering, idempotency, replay) plus executor (motion, status)."""

    def __init__(self, executor: Executor, session_id: str | None = None) -> None:
        self.executor = executor
        self.receiver = CommandReceiver(session_id or uuid.uuid4().hex[:16])
        self.connected = False  # a console connection is open
        self.greeted = False  # ... and has said hello: reports may flow on it
        self.frame_number = 0

    # -- command channel ----------------------------------------------------------------------
    def connect(self) -> None:
        """A console connection opened. Nothing flows on it until its ``hello``: status reports
        produced before then are replayed after the ``welcome``, so the client never sees a
        newer report before the older ones it missed."""
        self.connected = True

    def disconnect(self) -> None:
        self.connected = False
        self.greeted = False
        self.receiver.disconnect()
        self.executor.hold_queue = True
        log.warning("console connection lost: finishing the current statement, starting nothing new")

    def on_text(self, text: str | bytes) -> list[BaseModel]:
        step = self.receiver.on_text(text)
        if any(isinstance(r, Welcome) for r in step.replies):
            self.greeted = True
            self.executor.hold_queue = False
        return self._apply(step)

    def on_unit(self, data: bytes) -> list[BaseModel]:
        return self._apply(self.receiver.on_unit(data))

    def _apply(self, step: ReceiverStep) -> list[BaseModel]:
        out: list[BaseModel] = list(step.replies)
        for number, statement in step.accepted:
            self.executor.enqueue(number, statement)
        for cmd in step.recoveries:
            if isinstance(cmd, Stop):
                applied, detail = self.executor.stop()
            elif isinstance(cmd, Resume):
                applied, detail = self.executor.resume()
            elif isinstance(cmd, SkipCurrent):
                applied, detail = self.executor.skip(cmd.number)
            elif isinstance(cmd, AbortFlush):
                applied, detail = self.executor.abort()
            else:  # pragma: no cover - the receiver only passes the four kinds
                applied, detail = False, f"unknown recovery {cmd!r}"
            log.info("recovery %s #%d: %s", cmd.type, cmd.command_id, detail)
            # reports the command caused (skipped, aborted) go out before its acknowledgement
            out += self._reports(self.executor.drain_events())
            out.append(self.receiver.ack(cmd, applied, detail, self.executor.snapshot()))
        return out

    # -- servo ----------------------------------------------------------------------------------
    def tick(self) -> list[BaseModel]:
        """One servo period; returns the status reports to send now (in order). Reports made
        while no greeted console is connected are kept by the receiver and replayed later."""
        reports = self._reports(self.executor.tick())
        return reports if self.greeted else []

    def _reports(self, events) -> list[BaseModel]:
        out = []
        for e in events:
            robot = e.snapshot if e.state is not StatementState.RUNNING else None
            out.append(self.receiver.report(e.number, e.state, e.reason, robot))
        return out

    # -- telemetry ------------------------------------------------------------------------------
    def telemetry(self) -> bytes:
        """The current state as one fixed-size binary frame."""
        snap = self.executor.snapshot()
        state = snap.state if self.connected else RobotState.DISCONNECTED
        self.frame_number += 1
        return encode_frame(
            TelemetryFrame(
                time=self.executor.time,
                frame=self.frame_number,
                state=state,
                mode=snap.mode,
                statement=self.executor.current_number,
                q=snap.q,
                position=snap.base_p_tool,
                rpy=snap.tool_rpy,
                gripper=snap.gripper,
                wrench=snap.wrench,
            )
        )
