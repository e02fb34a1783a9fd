"""Recovery commands (thesis §4.2.3): STOP, resume, skip, abort, and backing away from a contact.

STOP is for anybody, whoever holds control; the others need control. Each is a priority command
on the robot's channel, acknowledged after a round trip; the console lists it as pending until
the acknowledgement, never waits for it in a page handler, and says what the robot did.
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING

import numpy as np

from server.console.context import ConsoleContext
from server.console.enums import SentStatus
from server.console.control import as_caller
from server.console.errors import ConflictError
from server.console.events import ActionTaken, LinkChanged, Notice, SentChanged
from server.console.views import Caller, LinkView, SentListView
from shared.language.formatter import format_statement
from shared.language.statements import Draw, Mode, SetMode, Statement
from shared.motion.back_away import back_away_motion
from shared.wire.messages import RecoveryAck, RobotState

if TYPE_CHECKING:
    from server.console.control import ControlLock
    from server.console.dispatch import Dispatch
    from server.console.link_status import LinkStatus
    from server.console.program_desk import ProgramDesk
    from server.console.remote import RemoteMirror


class Recovery:
    """STOP, resume, skip, abort, back away."""

    def __init__(self, ctx: ConsoleContext, control: ControlLock, desk: ProgramDesk, dispatch: Dispatch, remote: RemoteMirror, link: LinkStatus) -> None:
        self._ctx = ctx
        self._control, self._desk, self._dispatch, self._remote, self._link = control, desk, dispatch, remote, link
        self.pending: dict[int, str] = {}
        self._keys = itertools.count(1)  # next() is atomic: STOP takes a key without the lock

    def stop(self, *, client: Caller | str | None = None) -> LinkView:
        """STOP: the robot halts and waits. Anybody may press STOP, whoever holds control."""
        return self._recover("stop", lambda r: r.stop(), None)

    def resume(self, *, client: Caller | str | None = None) -> LinkView:
        return self._recover("resume", lambda r: r.resume(), client)

    def skip(self, number: int | None = None, *, client: Caller | str | None = None) -> LinkView:
        """Skip statement ``number`` (default: the one running, else the first not final)."""
        with self._ctx.lock:
            if number is None:
                frame = self._remote.telemetry
                if frame is not None and frame.statement:
                    number = frame.statement
                else:
                    number = next((s.number for s in self._dispatch.sent if not s.final and s.number is not None), None)
            if number is None:
                raise ConflictError("nothing to skip: no statement is running or waiting")
        n = int(number)
        return self._recover(f"skip {n}", lambda r: r.skip(n), client)

    def abort(self, *, client: Caller | str | None = None) -> LinkView:
        """Flush every statement the robot has not finished."""
        return self._recover("abort", lambda r: r.abort(), client)

    def back_away_motion(self) -> Draw:
        """The motion that backs the remote arm out of a contact fault
        (``shared.motion.back_away``): refused unless the robot reports a fault, or when no
        motion can be planned from where it stopped."""
        ctx = self._ctx
        with ctx.lock:
            frame = self._remote.telemetry
            if frame is None:
                raise ConflictError("no telemetry from the robot yet: back away needs to know where it stopped")
            if frame.state is not RobotState.FAULT:
                raise ConflictError(f"back away is for a robot in fault after a contact; the robot is {frame.state.name.lower()}")
            q = ctx.robot.as_q(np.array(frame.q, dtype=float))
            failed = max((s for s in self._dispatch.sent if s.status is SentStatus.FAILED), key=lambda s: s.finished_at or 0.0, default=None)
        answer = back_away_motion(ctx.robot, ctx.cell, ctx.frames, q, failed.statement if failed is not None else None,
                                  distance=ctx.settings.back_away_distance, speed=ctx.settings.back_away_speed)
        if answer.motion is None:
            raise ConflictError(f"cannot back away from where the robot stopped: {answer.refusal}")
        return answer.motion

    def back_away(self, *, client: Caller | str | None = None) -> SentListView:
        """After a contact fault, one click: abort what the robot has not finished (it waits in
        fault until then), then send :meth:`back_away_motion`. The motion joins the sent list,
        not the program; the program's start is unknown until a re-sync."""
        motion = self.back_away_motion()
        dispatch = self._dispatch
        with self._ctx.lock:
            self._control.check(client)
            robot, loop = dispatch.need_robot()
            outgoing: list[Statement] = [motion]
            if dispatch.robot_mode is Mode.FORCE:
                outgoing.insert(0, SetMode(mode=Mode.POSITION))  # joins the sent list: robot_mode follows
            comm = dispatch.open_communication(outgoing)
            self._desk.start.unknown = True  # the program goes on from where the robot ends: re-sync
            key = self._open("abort before back away")

        async def run() -> None:
            try:
                await robot.abort()
            except Exception as exc:  # noqa: BLE001 - shown, and the motion is not sent
                self._ctx.after.post(self._back_away_refused, key, comm, exc)
                return
            # the abort is applied: the motion goes out now, from this loop; the lists follow
            self._ctx.after.post(self._close_and_show, key)
            await dispatch.send(robot, comm, outgoing)

        asyncio.run_coroutine_threadsafe(run(), loop)
        view = dispatch.view()
        self._ctx.bus.emit([ActionTaken(action="back_away", client=as_caller(client).name, detail=format_statement(motion)),
                            SentChanged(sent=view), LinkChanged(link=self._link.view()),
                            Notice(level="info", message=f"backing away: abort, then {format_statement(motion)}")])
        return view

    def _open(self, what: str) -> int:
        key = next(self._keys)
        self.pending[key] = what
        return key

    def _close(self, key: int) -> None:
        with self._ctx.lock:
            self.pending.pop(key, None)

    def _close_and_show(self, key: int) -> None:
        self._close(key)
        self._ctx.bus.emit([LinkChanged(link=self._link.view())])

    def _back_away_refused(self, key: int, comm: int, exc: Exception) -> None:
        self._close(key)
        self._dispatch.finish_communication(comm, SentStatus.REJECTED, f"abort failed: {exc}")
        self._ctx.bus.emit([Notice(level="error", message=f"back away not sent: abort failed: {exc}")])

    def _recover(self, what: str, call: Callable[[object], Awaitable[RecoveryAck]], client: Caller | str | None) -> LinkView:
        if what == "stop":
            # STOP goes out before anything else: no control check (anybody may stop) and no
            # wait for the session's lock, which a long computation may hold; the robot client's
            # loop sends it at once. The pending entry and the events follow.
            robot, loop = self._dispatch.need_robot()
            key = next(self._keys)
            # listed before it is sent, so its acknowledgement always finds it; one dict store is
            # atomic, and the link view copies the dict in one step too
            self.pending[key] = what
            self._schedule(what, key, call, robot, loop)
        else:
            with self._ctx.lock:
                self._control.check(client)
                robot, loop = self._dispatch.need_robot()
                key = self._open(what)
            self._schedule(what, key, call, robot, loop)
        view = self._link.view()
        action, _, detail = what.partition(" ")
        self._ctx.bus.emit([ActionTaken(action=action, client=as_caller(client).name, detail=detail), LinkChanged(link=view)])
        return view

    def _schedule(self, what: str, key: int, call: Callable[[object], Awaitable[RecoveryAck]], robot, loop) -> None:
        """Send the command on the robot client's loop; what its acknowledgement changes runs on
        the console's ``after`` thread (the loop never waits for the session's lock)."""
        async def run() -> None:
            t0 = self._ctx.clock()
            try:
                ack = await call(robot)
            except Exception as exc:  # noqa: BLE001 - told, never lost
                self.pending.pop(key, None)
                self._ctx.after.post(self._acknowledged, what, key, None, None, exc)
                return
            # answered: no longer pending at once (one dict step on this loop, no lock), so the
            # link's view shows it while the after thread may still wait for the session's lock
            self.pending.pop(key, None)
            self._ctx.after.post(self._acknowledged, what, key, ack, self._ctx.clock() - t0, None)

        asyncio.run_coroutine_threadsafe(run(), loop)

    def _acknowledged(self, what: str, key: int, ack: RecoveryAck | None, round_trip: float | None,
                      error: Exception | None) -> None:
        if error is not None:
            self._ctx.bus.emit([Notice(level="error", message=f"{what} failed: {error}")])
        self.pending.pop(key, None)  # (popped on the loop already; a fake robot's tests call this directly)
        if round_trip is not None:
            self._dispatch.note_round_trip(round_trip)
        if ack is not None:
            with self._ctx.lock:
                self._remote.take_reported_objects(ack.robot)
        if ack is not None:
            level = "info" if ack.applied else "warning"
            detail = f": {ack.detail}" if ack.detail else ""
            self._ctx.bus.emit([Notice(level=level, message=f"robot {'applied' if ack.applied else 'did not apply'} {what}{detail}")])
        self._ctx.bus.emit([LinkChanged(link=self._link.view())])
