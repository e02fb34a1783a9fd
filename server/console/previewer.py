"""The previewer (thesis §4.3.7 task preview): plan a range of the program from its start state,
check it once for collisions and joint limits (``shared.motion.plan_check``), then show it as a
pure function of time.

Playing is the caller's clock, not a thread: ``play`` notes when it began on the session's
clock, every view reads the time from that, and :meth:`tick` (the app's loop calls it at the
player rate; a test calls it after moving its virtual clock) publishes the moving preview and
settles it at its end. A range previewed to its end without warnings is confirmed for the
quasi-operation regime.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from server.console.context import ConsoleContext
from server.console.errors import ConflictError, RefusedByRule
from server.console.events import PreviewChanged, ProgramChanged, SessionEvent
from server.console.views import Caller, PreviewView, PreviewWarning
from shared.errors import InputError, TeleprogError
from shared.language.formatter import format_statement
from shared.motion.plan_check import PlanCheck, check_plan, plan_or_refuse
from shared.program.editor import Refusal

if TYPE_CHECKING:
    from server.console.control import ControlLock
    from server.console.modes import Modes
    from server.console.program_desk import ProgramDesk
    from shared.collision.cell_check import CellCollision

UNKNOWN_START = ("the robot's state after the statements sent is not known here (a task, a stop or a failure): "
                 "the preview starts from the last prediction; re-sync from telemetry first")


@dataclass
class _Showing:
    """A range being previewed: its check, its warnings, and where the player stands."""

    check: PlanCheck
    warnings: list[PreviewWarning]
    t: float = 0.0  # range time at ``since`` (or now, when paused)
    playing: bool = False
    rate: float = 1.0
    since: float = 0.0  # session clock when playing began

    def time(self, now: float) -> float:
        if not self.playing:
            return self.t
        return min(self.t + (now - self.since) * self.rate, self.check.duration)


class Previewer:
    """Plan, check and play a range of the program."""

    def __init__(self, ctx: ConsoleContext, collision: CellCollision, control: ControlLock, modes: Modes, desk: ProgramDesk, arm_objects: Callable[[], tuple[dict[str, np.ndarray], str | None]]) -> None:
        self._ctx = ctx
        self._collision = collision
        self._control, self._modes, self._desk = control, modes, desk
        self._arm = arm_objects  # callable: () -> (object poses, held) of the virtual world (under the lock)
        self._showing: _Showing | None = None
        self._ticking = False
        self._data = collision.new_data()

    def running_range(self) -> tuple[int, int] | None:
        """The range being previewed, or None (under the lock or not)."""
        with self._ctx.lock:
            s = self._showing
            return None if s is None else (s.check.start, s.check.stop)

    # -- checking ------------------------------------------------------------------------------
    def check(self, start: int, stop: int) -> tuple[PlanCheck, list[PreviewWarning]]:
        """Plan the program's first ``stop`` statements from its start and check ``start..stop-1``
        (under the lock)."""
        statements = list(self._desk.editor.state.statements[:stop])
        ctx = self._ctx
        plan = plan_or_refuse(statements, ctx.robot, ctx.cell, self._desk.start.q)
        poses, _held = self._arm()
        checked = check_plan(plan, ctx.robot, self._collision, start, stop, object_poses=poses or None,
                             dt=ctx.settings.preview_dt, max_samples=ctx.settings.preview_max_samples)
        warnings = [PreviewWarning(t=0.0, index=start, kind="plan", message=UNKNOWN_START)] if self._desk.start.unknown else []
        warnings += [PreviewWarning(t=i.t, index=i.index, kind=i.kind, message=i.message, bodies=i.bodies) for i in checked.issues]
        return checked, warnings

    def hazard(self) -> str | None:
        """Why the program may not stream to the robot now, or None: its planned path from where
        the sent statements end touches something with the arm, leaves a joint range, or cannot
        be planned."""
        with self._ctx.lock:
            statements = list(self._desk.editor.state.statements)
            _poses, held = self._arm()
            try:
                checked, _ = self.check(0, len(statements))
            except TeleprogError as exc:
                return f"the program cannot be planned: {exc}"
        if checked.refusal is not None:
            return checked.refusal
        for issue in checked.issues:
            if issue.kind == "joint_limit" or (issue.kind == "collision" and self._collision.involves_arm(issue.bodies, held)):
                return issue.message.replace(": ", f" ({format_statement(statements[issue.index])}): ", 1)
        return None

    def path_not_clear(self, start: int, stop: int) -> dict[int, str]:
        """For each statement of ``start..stop-1`` whose planned path is not clear, why: the arm
        touches something, a joint leaves its range, or the plan is refused there (program
        index -> sentence; under the lock). The operation regime reads it for actions without UNTIL."""
        _poses, held = self._arm()
        checked, _ = self.check(start, stop)
        found: dict[int, str] = {}
        for issue in checked.issues:
            if issue.kind in ("plan", "joint_limit") or (issue.kind == "collision" and self._collision.involves_arm(issue.bodies, held)):
                found.setdefault(issue.index, issue.message)
        return found

    # -- showing -------------------------------------------------------------------------------
    def view(self) -> PreviewView:
        with self._ctx.lock:
            s = self._showing
            if s is None:
                return PreviewView()
            self._settle(s)
            c = s.check
            t = s.time(self._ctx.clock())
            q = c.q_at(t)
            current = c.statement_at(t) if len(c.plan.start_times) else None
            poses, held = self._arm()
            pairs, report = self._collision.touching(q, object_poses=poses or None, held=held, data=self._data, triangles=True)
            bodies = {n for p in report.pairs for n in (p.a, p.b)}
            return PreviewView(
                active=True, start=c.start, stop=c.stop, playing=s.playing, t=t, duration=c.duration, rate=s.rate,
                current=current, q=q.tolist(), warnings=list(s.warnings), colliding_now=report.colliding or len(pairs) > len(report.pairs),
                triangles={b: report.interfering_triangles(b).tolist() for b in bodies}, refusal=c.refusal,
            )

    def begin(self, start: int, stop: int, *, client: Caller | str | None = None) -> PreviewView:
        """Plan ``statements[start:stop]`` from the program's start state and stand at its start.
        The statements before ``start`` are planned too (they set where the range starts)."""
        with self._ctx.lock:
            self._control.check(client)
            editor = self._desk.editor
            refusal = editor.begin_preview(start, stop)
            if isinstance(refusal, Refusal):
                raise RefusedByRule(refusal)
            try:
                checked, warnings = self.check(start, stop)
            except TeleprogError:
                editor.end_preview()
                raise
            self._showing = _Showing(checked, warnings)
            display = self._modes.enter_preview()
        view = self.view()
        self._ctx.bus.emit([PreviewChanged(preview=view), ProgramChanged(program=self._desk.view()), display])
        return view

    def play(self, rate: float = 1.0, *, client: Caller | str | None = None) -> PreviewView:
        """Play from the current time at ``rate`` x real time (from the start when at the end)."""
        if not (0 < rate <= 100):
            raise InputError(f"preview rate must be in (0, 100], got {rate}")
        with self._ctx.lock:
            self._control.check(client)
            s = self._need()
            now = self._ctx.clock()
            s.t = s.time(now)
            if s.t >= s.check.duration:
                s.t = 0.0
            s.playing, s.rate, s.since = True, float(rate), now
        return self._publish()

    def pause(self, *, client: Caller | str | None = None) -> PreviewView:
        with self._ctx.lock:
            self._control.check(client)
            s = self._need()
            s.t, s.playing = s.time(self._ctx.clock()), False
        return self._publish()

    def seek(self, t: float, *, client: Caller | str | None = None) -> PreviewView:
        """Stand at preview time ``t`` (s from the range's start, clipped into the range)."""
        with self._ctx.lock:
            self._control.check(client)
            s = self._need()
            s.t, s.since = float(min(max(t, 0.0), s.check.duration)), self._ctx.clock()
            self._maybe_confirm(s)
        return self._publish()

    def step(self, statements: int = 1, *, client: Caller | str | None = None) -> PreviewView:
        """Jump to the end of the current statement (``statements`` > 0) or to the start of the
        previous one (< 0)."""
        with self._ctx.lock:
            self._control.check(client)
            s = self._need()
            s.t, s.playing = s.time(self._ctx.clock()), False
            eps = 1e-9
            if statements > 0:
                later = [e for e in s.check.statement_ends() if e > s.t + eps] or [s.check.duration]
                s.t = later[min(statements, len(later)) - 1]
            elif statements < 0:
                earlier = [b for b in s.check.statement_starts() if b < s.t - eps] or [0.0]
                s.t = earlier[max(len(earlier) + statements, 0)]
            s.t = min(max(s.t, 0.0), s.check.duration)
            self._maybe_confirm(s)
        return self._publish()

    def end(self, *, client: Caller | str | None = None) -> PreviewView:
        """Stop previewing; the arm is drawn where the operator left it again."""
        with self._ctx.lock:
            self._control.check(client)
            self._need()
            self._showing = None
            self._desk.editor.end_preview()
            display = self._modes.leave_preview()
        view = PreviewView()
        self._ctx.bus.emit([PreviewChanged(preview=view), ProgramChanged(program=self._desk.view()), display])
        return view

    def tick(self) -> None:
        """Publish a playing preview (and the moment it reaches its end): the app's loop calls
        this at the player rate."""
        with self._ctx.lock:
            s = self._showing
            was, self._ticking = self._ticking, False
            if s is None:
                return
            self._settle(s)
            self._ticking = s.playing
            publish = s.playing or was
        if publish:
            self._publish()

    # -- inside --------------------------------------------------------------------------------
    def _need(self) -> _Showing:
        if self._showing is None:
            raise ConflictError("no preview is running; begin one with a range of statements")
        return self._showing

    def _settle(self, s: _Showing) -> None:
        """A playing preview that reached its end stops there (and may confirm the range)."""
        if s.playing and s.time(self._ctx.clock()) >= s.check.duration:
            s.t, s.playing = s.check.duration, False
            self._maybe_confirm(s)

    def _maybe_confirm(self, s: _Showing) -> None:
        if s.t >= s.check.duration - 1e-9 and not s.warnings:
            self._desk.confirm(s.check.start, s.check.stop)

    def _publish(self) -> PreviewView:
        view = self.view()
        events: list[SessionEvent] = [PreviewChanged(preview=view)]
        if view.active and not view.playing and view.t >= view.duration:
            events.append(ProgramChanged(program=self._desk.view()))
        self._ctx.bus.emit(events)
        return view
