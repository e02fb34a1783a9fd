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
from typing import TYPE_CHECKING

from server.console.enums import SentStatus
from server.console.events import Notice, SentChanged

if TYPE_CHECKING:
    from server.console.dispatch import Dispatch
    from server.robot_client import RobotAccount

log = logging.getLogger(__name__)

BEFORE = "sent before this console started (the robot's account when it connected)"


def take_account(dispatch: Dispatch, account: RobotAccount) -> None:
    """Put what the welcome lists into ``dispatch``'s sent list (on the delivery thread). A part
    of ``Dispatch`` in a room of its own: it works on the dispatch's books under its lock."""
    from server.console.dispatch import Sent

    ctx, welcome = dispatch._ctx, account.welcome
    # what the robot holds, whoever sent it (a resume runs it all); of what it ran, this identity's
    ran = [h for h in welcome.ran if h.client_id == account.client_id]
    listed = [h for h in (*ran, *welcome.holds) if h.statement is not None]
    with ctx.lock:
        dispatch.history_below = welcome.numbered + 1
        known = {s.number for s in dispatch.sent if s.number is not None}
        fresh = [h for h in sorted(listed, key=lambda h: h.number) if h.number not in known]
        if not fresh:
            return
        dispatch._comms += 1
        now = ctx.wall_clock()
        adopted = [Sent(0, h.statement, SentStatus(h.state), now, dispatch._comms, number=h.number, reason=BEFORE,
                        answered_at=now, before=True) for h in fresh]
        dispatch.sent[:0] = adopted  # before anything this console sent since it started
        for i, s in enumerate(dispatch.sent, start=1):
            s.id = i
        for s in adopted:
            dispatch._by_number[s.number] = s
            for report in dispatch._early.pop(s.number, []):
                dispatch._apply_report(s, report)
        for report in account.reports:  # those that came before the session asked (a repeat changes nothing)
            if (s := dispatch._by_number.get(report.number)) is not None and s.before:
                dispatch._apply_report(s, report)
        unfinished = [s for s in adopted if not s.final]
        if unfinished:
            dispatch._desk.start.unknown = True  # the robot will end where they end, not where the program starts
    held = sum(s.status is SentStatus.RECEIVED for s in adopted)
    running = [s.number for s in adopted if s.status is SentStatus.RUNNING]
    text = (f"the robot holds {held} statement(s)" + (f" and runs #{running[0]}" if running else "")
            + f" sent before this console started; {len(adopted) - len(unfinished)} more finished"
            + (f"; halted: {welcome.halted}" if welcome.halted else "")
            + (f" (it holds {welcome.holds_total} in all; the list shows {len(welcome.holds)})"
               if welcome.holds_total > len(welcome.holds) else ""))
    log.warning("%s", text)
    dispatch._ctx.bus.emit([SentChanged(sent=dispatch.view()),
                           Notice(level="warning" if unfinished else "info", message=text)])
    dispatch.remote.refresh_predicted()
