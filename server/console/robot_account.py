"""The robot's account at this console's first welcome, taken into the sent list.

A console that starts again (after a crash, a kill, an upgrade) while its robot holds statements
must show them before anybody presses Resume: Resume runs what is held, and an operator may only
resume what they can see. The robot's first welcome to this console lists what it runs and holds
(``Welcome.holds``, whoever sent it) and the newest statements it finished (``Welcome.ran``, of
which those this console's identity sent are its own history), with their numbers, statements
and statuses (``shared.wire.messages.HeldStatement``). They join the sent list before
anything this console sends, marked as from before this console (``Sent.before``), and the
reports the robot replays next move them on as any other. Reports of older statements the
account does not list (numbered before this console arrived) are history the list cannot show:
they are dropped (``Dispatch.history_below``) rather than kept waiting for numbers that never come.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING

from server.console.enums import SentStatus
from server.console.events import Notice, SentChanged
from server.console.sent import Sent

if TYPE_CHECKING:
    from server.console.context import ConsoleContext
    from server.console.ports import RemoteSink
    from server.console.program_start import ProgramStart
    from server.console.views import SentListView
    from server.robot_client import RobotAccount
    from shared.wire.messages import StatusReport

log = logging.getLogger(__name__)

BEFORE = "sent before this console started (the robot's account when it connected)"


class _StartHolder:  # the program desk, as far as the account reads it
    start: ProgramStart


class AccountBooks:
    """The part of ``Dispatch`` that takes the robot's account, in a room of its own: it works on
    the dispatch's books (these attributes are the dispatch's) under the session's lock."""

    _ctx: ConsoleContext
    _desk: _StartHolder
    _comms: int
    _by_number: dict[int, Sent]
    _early: dict[int, list[StatusReport]]
    sent: list[Sent]
    history_below: int
    remote: RemoteSink | None

    _apply_report: Callable[[Sent, StatusReport], None]
    view: Callable[[], SentListView]

    def take_account(self, account: RobotAccount) -> None:
        """Put what the welcome lists into the sent list (on the delivery thread)."""
        ctx, welcome = self._ctx, account.welcome
        # what the robot holds, whoever sent it (a resume runs it all); of what it ran, this identity's
        ran = [h for h in welcome.ran if h.client_id == account.client_id]
        listed = [h for h in (*ran, *welcome.holds) if h.statement is not None]
        with ctx.lock:
            self.history_below = welcome.numbered + 1
            known = {s.number for s in self.sent if s.number is not None}
            fresh = [h for h in sorted(listed, key=lambda h: h.number) if h.number not in known]
            if not fresh:
                return
            self._comms += 1
            now = ctx.wall_clock()
            adopted = [Sent(0, h.statement, SentStatus(h.state), now, self._comms, number=h.number, reason=BEFORE,
                            answered_at=now, before=True) for h in fresh]
            self.sent[:0] = adopted  # before anything this console sent since it started
            for i, s in enumerate(self.sent, start=1):
                s.id = i
            for s in adopted:
                self._by_number[s.number] = s
                for report in self._early.pop(s.number, []):
                    self._apply_report(s, report)
            for report in account.reports:  # those that came before the session asked (a repeat changes nothing)
                if (s := self._by_number.get(report.number)) is not None and s.before:
                    self._apply_report(s, report)
            unfinished = [s for s in adopted if not s.final]
            if unfinished:
                self._desk.start.unknown = True  # the robot will end where they end, not where the program starts
        held = sum(s.status is SentStatus.RECEIVED for s in adopted)
        running = [s.number for s in adopted if s.status is SentStatus.RUNNING]
        text = (f"the robot holds {held} statement(s)" + (f" and runs #{running[0]}" if running else "")
                + f" sent before this console started; {len(adopted) - len(unfinished)} more finished"
                + (f"; halted: {welcome.halted}" if welcome.halted else "")
                + (f" (it holds {welcome.holds_total} in all; the list shows {len(welcome.holds)})"
                   if welcome.holds_total > len(welcome.holds) else ""))
        log.warning("%s", text)
        self._ctx.bus.emit([SentChanged(sent=self.view()),
                               Notice(level="warning" if unfinished else "info", message=text)])
        self.remote.refresh_predicted()
