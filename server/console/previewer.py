"""The previewer (thesis §4.3.7 task preview): plan a range of the program from its start state,
check it once for collisions and joint limits (``shared.motion.plan_check``), then show it as a
pure function of time.

Playing is the caller's clock, not a thread: ``play`` notes when it began on the session's
clock, every view reads the time from that, and :meth:`tick` (the app's loop calls it at the
player rate; a test calls it after moving its virtual clock) publishes the moving preview and
settles it at its end. A range previewed to its end without warnings is confirmed for the
quasi-operation regime.

The preview speed (:meth:`Previewer.set_speed`) scales plan time per clock second (1x, 2x, 5x,
10x, any factor up to 100) or is ``"instant"``: play then stands at the range's end at once.
"Preview and submit" (:meth:`Previewer.preview_and_submit`) previews a range at that speed and,
when it reaches its end without warnings, ends the preview and submits the range.

Why "instant" may confirm (thesis §4.2.1, §4.3.6-4.3.7, §2.2.2 on predictive display): the thesis's
preview is for path verification and collision detection, and its confirmation is the
operator's. Here the check is not the playback: ``check_plan`` samples the whole range for
collisions and joint limits when the preview begins, whatever the speed, so every warning is
known before a frame plays and a faster (or no) playback weakens no check. The thesis's own
predictive display runs its simulator "much faster than the real process" (§2.2.2); and the player
already let an operator step or scrub to the end to confirm. What the operator gives up with
"instant" is watching the motion; choosing it and clicking "Preview and submit" is that
operator's explicit confirmation. A range with any warning is never confirmed, at any speed.
"""

from __future__ import annotations

import logging
import threading

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from server.console.context import ConsoleContext
from server.console.enums import Regime
from server.console.errors import ConflictError, RefusedByRule
from server.console.events import Notice, PreviewChanged, ProgramChanged, SessionEvent
from server.console.views import Caller, PreviewAndSubmitView, PreviewView, PreviewWarning, SentListView
from shared.errors import InputError, TeleprogError
from shared.language.formatter import format_statement
from shared.motion.plan_check import PlanCheck, check_plan
from shared.program.editor import Refusal

if TYPE_CHECKING:
    from server.console.control import ControlLock
    from server.console.modes import Modes
    from server.console.program_desk import ProgramDesk
    from shared.collision.cell_check import CellCollision

log = logging.getLogger(__name__)
Speed = float | Literal["instant"]
INSTANT = "instant"
MAX_SPEED = 100.0
SEND_WAIT_S = 5.0  # how long a "Preview and submit" waits for a send another thread has begun


def checked_speed(speed: Speed) -> Speed:
    """A preview speed: a factor in (0, 100] (plan seconds per clock second) or "instant"."""
    if speed == INSTANT:
        return INSTANT
    if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not (0 < float(speed) <= MAX_SPEED):
        raise InputError(f"preview speed must be a factor in (0, {MAX_SPEED:g}] or 'instant', got {speed!r}")
    return float(speed)


@dataclass
class _SendAfter:
    """A "Preview and submit" waiting for its preview to end without warnings."""

    start: int
    stop: int
    client: Caller | str | None
    due: bool = False  # the range was confirmed: send at the next chance, outside the lock
    sent: SentListView | None = None  # what the send gave, whichever thread made it (the player's tick, say)
    finished: threading.Event = field(default_factory=threading.Event)  # set once the send was made or refused
    refusal: str | None = None  # why the send was refused (also a notice)


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
        self._speed: Speed = 1.0
        self._send_after: _SendAfter | None = None
        self.submit: Callable[..., SentListView] | None = None  # set by the session: Dispatch.submit
        self.submit_refusal: Callable[..., str | None] | None = None  # set by the session: Dispatch.refusal
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
        ctx = self._ctx
        # the program's own planner: what its durations planned is not planned again
        plan = self._desk.prefix_planner(self._desk.start.q).plan_first(self._desk.editor.state.statements, stop)
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
                return PreviewView(speed=self._speed)
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
                speed=self._speed, then_submit=self._send_after is not None,
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
            self._send_after = None
            display = self._modes.enter_preview()
        view = self.view()
        self._ctx.bus.emit([PreviewChanged(preview=view), ProgramChanged(program=self._desk.view()), display])
        return view

    def play(self, rate: float | None = None, *, client: Caller | str | None = None) -> PreviewView:
        """Play from the current time at ``rate`` x real time (default: the preview speed; from
        the start when at the end). At the speed "instant" the player stands at the end at once."""
        if rate is not None and not (0 < rate <= MAX_SPEED):
            raise InputError(f"preview rate must be in (0, {MAX_SPEED:g}], got {rate}")
        with self._ctx.lock:
            self._control.check(client)
            s = self._need()
            self._start_playing(s, self._speed if rate is None else float(rate))
        view = self._publish()
        self._send_if_due()
        return view

    def set_speed(self, speed: Speed, *, client: Caller | str | None = None) -> PreviewView:
        """The preview speed for Play and "Preview and submit": a factor in (0, 100] or
        "instant"; a preview playing now goes on at the new speed."""
        self._control.check(client)  # the lock answers before the value is looked at
        speed = checked_speed(speed)
        with self._ctx.lock:
            self._control.check(client)
            self._speed = speed
            s = self._showing
            if s is not None and s.playing:
                now = self._ctx.clock()
                s.t, s.since = s.time(now), now
                if speed == INSTANT:
                    s.t, s.playing = s.check.duration, False
                    self._maybe_confirm(s)
                else:
                    s.rate = float(speed)
        view = self._publish()
        self._send_if_due()
        return view

    def preview_and_submit(self, start: int, stop: int, *, client: Caller | str | None = None) -> PreviewAndSubmitView:
        """Preview ``statements[start:stop]`` at the preview speed and, if it reaches its end
        without warnings, end the preview and submit the range (at once for "instant"; else
        when the player gets there, on the session's clock). Refused before previewing when the
        range could not be sent anyway (no robot, the editor's range rule, a statement's check;
        in the single-step regime its rules too). A range with warnings is not sent: the player
        stands at the first warning and a notice says so."""
        with self._ctx.lock:
            self._control.check(client)
            if self.submit is None or self.submit_refusal is None:
                raise ConflictError("submission is not wired to this previewer")
            # the quasi regime's rule is what this previews for; every other check applies now
            blocker = self.submit_refusal(start, stop, regime=self._modes.regime is not Regime.QUASI)
            if blocker is not None:
                raise ConflictError(f"preview and submit: not started: {blocker}")
        view = self.begin(start, stop, client=client)
        if view.warnings or view.refusal:
            first = view.warnings[0] if view.warnings else None
            view = self.seek(first.t if first is not None else view.duration, client=client)
            why = first.message if first is not None else view.refusal
            message = (f"preview and submit: statements {start + 1}-{stop} not sent: the preview has "
                       f"{len(view.warnings)} warning(s); first: {why}")
            self._ctx.bus.emit([Notice(level="warning", message=message)])
            return PreviewAndSubmitView(preview=view, submitted=False, message=message)
        with self._ctx.lock:
            s = self._need()
            after = self._send_after = _SendAfter(start, stop, client)
            self._start_playing(s, self._speed)
        self._publish()
        sent = self._send_if_due()
        if sent is None and after.due:  # another thread (the player's tick) claimed the send: wait for it
            after.finished.wait(SEND_WAIT_S)
            sent = after.sent
        if sent is not None:
            return PreviewAndSubmitView(preview=self.view(), submitted=True, sent=sent,
                                        message=f"statements {start + 1}-{stop} previewed and sent")
        view = self.view()
        if view.then_submit:
            return PreviewAndSubmitView(preview=view, message=f"previewing {start + 1}-{stop}; sent when it ends without warnings")
        return PreviewAndSubmitView(preview=view, message=after.refusal or "not sent (see the notice)")

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
        view = self._publish()
        self._send_if_due()
        return view

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
        view = self._publish()
        self._send_if_due()
        return view

    def end(self, *, client: Caller | str | None = None) -> PreviewView:
        """Stop previewing; the arm is drawn where the operator left it again."""
        with self._ctx.lock:
            self._control.check(client)
            self._need()
            self._showing = None
            self._send_after = None
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
        self._send_if_due()

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

    def _start_playing(self, s: _Showing, speed: Speed) -> None:
        """Play from where the player stands (from the start when at the end), at ``speed``
        (under the lock)."""
        now = self._ctx.clock()
        s.t = s.time(now)
        if s.t >= s.check.duration:
            s.t = 0.0
        if speed == INSTANT:
            s.t, s.playing, s.since = s.check.duration, False, now
            self._maybe_confirm(s)
            return
        s.playing, s.rate, s.since = True, float(speed), now

    def _maybe_confirm(self, s: _Showing) -> None:
        if s.t >= s.check.duration - 1e-9 and not s.warnings:
            self._desk.confirm(s.check.start, s.check.stop)
            after = self._send_after
            if after is not None and (after.start, after.stop) == (s.check.start, s.check.stop):
                after.due = True

    def _send_if_due(self) -> SentListView | None:
        """A "Preview and submit" whose preview reached its end without warnings: end the
        preview and submit the range (outside the lock); a refusal becomes a notice."""
        with self._ctx.lock:
            after = self._send_after
            if after is None or not after.due:
                return None
            self._send_after = None
        try:
            self.end(client=after.client)
            after.sent = self.submit(after.start, after.stop, client=after.client)
            return after.sent
        except TeleprogError as exc:
            message = exc.refusal.message if isinstance(exc, RefusedByRule) else str(exc)
            after.refusal = f"preview and submit: statements {after.start + 1}-{after.stop} previewed but not sent: {message}"
            log.warning("%s", after.refusal)  # headless clients read the notice in the session's log too
            self._ctx.bus.emit([Notice(level="error", message=after.refusal)])
            return None
        finally:
            after.finished.set()

    def _publish(self) -> PreviewView:
        view = self.view()
        events: list[SessionEvent] = [PreviewChanged(preview=view)]
        if view.active and not view.playing and view.t >= view.duration:
            events.append(ProgramChanged(program=self._desk.view()))
        self._ctx.bus.emit(events)
        return view
