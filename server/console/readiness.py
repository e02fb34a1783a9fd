"""What Submit needs, said before the click (thesis §4.2.1: each regime has its own way of
sending), and whether the operator's drags stream to the robot.

The regimes, in the words the page uses:

* ONLINE (free zone): statements go as they are; with automatic generation on and a robot,
  every generated statement is sent the moment it is made, so a drag runs on the robot.
* OFFLINE (quasi-operation): a range goes only after it was previewed to its end without
  warnings, unchanged since ("Preview and submit" does both in one click).
* SINGLE STEP (operation): one motion at a time (parameter statements may go with it), once the
  previous step is final; a move with an UNTIL end condition runs in force mode, one without it
  needs a clear path in the model and runs in position mode (``Dispatch``'s docstring).

Whether a range may go now is never decided here: :meth:`Readiness.view` asks
``Dispatch.refusal``, which runs ``Dispatch.submit``'s own checks without sending, so the line
the page shows and the refusal a click would get cannot disagree. This room only puts the
regime's condition into words and says how far the range is from it. It listens to the session's
events and republishes :class:`ReadinessChanged` for the whole program whenever the answer changes.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from server.console.context import ConsoleContext
from server.console.enums import Regime
from server.console.events import (
    PreviewChanged,
    ProgramChanged,
    ReadinessChanged,
    RegimeChanged,
    SentChanged,
    SessionEvent,
)
from server.console.views import SubmitReadiness

if TYPE_CHECKING:
    from server.console.dispatch import Dispatch
    from server.console.modes import Modes
    from server.console.previewer import Previewer
    from server.console.program_desk import ProgramDesk

log = logging.getLogger(__name__)

REGIME_NAMES = {Regime.FREE: "ONLINE", Regime.QUASI: "OFFLINE", Regime.OPERATION: "SINGLE STEP"}
_WATCHED = (ProgramChanged, PreviewChanged, SentChanged, RegimeChanged)


def span(start: int, stop: int) -> str:
    """Statements ``start..stop-1`` as the operator counts them: "1-5", or "3" for one."""
    return f"{start + 1}" if stop - start == 1 else f"{start + 1}-{stop}"


class Readiness:
    """What Submit needs for a range, and whether drags stream (see the module docstring)."""

    def __init__(self, ctx: ConsoleContext, modes: Modes, desk: ProgramDesk, dispatch: Dispatch, preview: Previewer) -> None:
        self._ctx = ctx
        self._modes, self._desk, self._dispatch, self._preview = modes, desk, dispatch, preview
        self._last: SubmitReadiness | None = None
        ctx.bus.subscribe(self._on_event)

    # -- reading -------------------------------------------------------------------------------
    def streams(self) -> bool:
        """Generated statements go to the robot as they are made: the free regime, automatic
        generation on and a robot configured (what ``ProgramDesk.take_generated`` streams on)."""
        with self._ctx.lock:
            return (self._modes.regime is Regime.FREE and self._desk.view().auto_generate
                    and self._dispatch.connected)

    def view(self, start: int = 0, stop: int | None = None) -> SubmitReadiness:
        """What Submit needs for ``statements[start:stop]`` (default: the whole program) now."""
        with self._ctx.lock:
            n = self._desk.editor.state.empty_index
            stop = n if stop is None else int(stop)
            start = int(start)
            regime = self._modes.regime
            blocker = self._dispatch.refusal(start, stop) if stop > start else None
            outside = self._dispatch.refusal(start, stop, regime=False) if blocker is not None else None
            through = self._dispatch.confirmed_through(stop)
            previous_final = self._dispatch.previous_final()
            confirmed = self._desk.confirmed_range()
            previewing = self._preview.running_range()
            streams = self.streams()
        name = REGIME_NAMES[regime]
        if stop <= start:
            needs = f"{name}: nothing to send"
            state = "the program is empty" if n == 0 else "the range is empty"
            return SubmitReadiness(regime=regime, start=start, stop=stop, ready=False, needs=needs, state=state,
                                   blocker=state, confirmed=confirmed, streams=streams, line=f"{needs}: {state}")
        rng = span(start, stop)
        if regime is Regime.QUASI:
            needs = f"{name}: statements {rng} must be previewed to their end without warnings"
        elif regime is Regime.OPERATION:
            needs = (f"{name}: one motion at a time, ended by its UNTIL condition or on a clear path; "
                     "the previous one must be final")
        else:
            needs = (f"{name}: statements go as they are" + ("; drags stream to the robot as you drive" if streams else ""))
        ready = blocker is None
        if ready:
            state = f"ready to send {rng}"
        elif previewing is not None:
            state = f"statements {span(*previewing)} are being previewed: end the preview first"
        elif outside is not None:  # not the regime's rule: no robot, the editor's range rule, a statement
            state = outside
        elif regime is Regime.QUASI and not through:
            if confirmed is not None and confirmed[0] == 0 and confirmed[1] > 0:
                state = f"only {span(0, confirmed[1])} previewed; Preview and submit previews {rng} and sends it"
            else:
                state = f"not yet previewed; Preview and submit previews {rng} and sends it"
        elif regime is Regime.OPERATION and not previous_final:
            state = "waiting until the previous statement is final"
        elif regime is Regime.OPERATION and blocker is not None:
            state = blocker.removeprefix("operation regime: ")
        else:
            state = blocker or ""
        line = f"Ready to send {rng} ({needs})" if ready else f"{needs} ({state})"
        return SubmitReadiness(regime=regime, start=start, stop=stop, ready=ready, needs=needs, state=state,
                               blocker=blocker, confirmed=confirmed, streams=streams, line=line)

    # -- republishing --------------------------------------------------------------------------
    def _on_event(self, event: SessionEvent) -> None:
        """A change that may change the answer: publish it when it did (bus listeners run after
        the session's lock is released)."""
        if not isinstance(event, _WATCHED):
            return
        view = self.view()
        with self._ctx.lock:
            if view == self._last:
                return
            self._last = view
        self._ctx.bus.emit([ReadinessChanged(readiness=view)])
