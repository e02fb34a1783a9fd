"""The link as the operator sees it: connected or not, the measured delay, the telemetry's age,
the robot's own halts and refusals, the processes ``teleprog up`` watches, and one line per
problem for the status bar. Published on a timer (its ages grow when nothing else changes)."""

from __future__ import annotations

import logging
import statistics
from collections.abc import Callable
from typing import TYPE_CHECKING

from server.console.context import ConsoleContext
from server.console.events import LinkChanged
from server.console.views import LinkView

if TYPE_CHECKING:
    from server.console.dispatch import Dispatch
    from server.console.ports import PendingRecoveries
    from server.console.remote import RemoteMirror

log = logging.getLogger(__name__)


def link_problems(h, children: dict[str, str]) -> list[str]:
    """What is wrong with the link, one line each (``h``: the client's ``ChannelHealth``)."""
    out = [f"{name} {what}" for name, what in children.items() if not what.startswith("running")]
    if h.door:
        out.append(f"the robot refuses this console: {h.door}")
    elif h.command == "down":
        out.append("link down")
    elif h.command == "silent":
        out.append(f"robot silent for {h.heard_ago_s:.1f} s")
    if h.telemetry == "stale":
        out.append(f"telemetry stale ({h.telemetry_ago_s:.1f} s)")
    if h.halted:
        out.append(f"robot halted by itself: {h.halted}")
    if h.buffer_full:
        out.append(f"robot buffer full: {h.buffer_full}")
    if h.errors:
        out.append(f"{h.errors} error(s) handling the robot's messages; last: {h.last_error}")
    return out


class LinkStatus:
    """The link view, and its publication on a timer."""

    def __init__(self, ctx: ConsoleContext, dispatch: Dispatch, remote: RemoteMirror) -> None:
        self._ctx = ctx
        self._dispatch, self._remote = dispatch, remote
        self.recovery: PendingRecoveries | None = None  # set by the session
        self._children: Callable[[], dict[str, str]] | None = None
        self._published_at: float | None = None

    def watch_children(self, status: Callable[[], dict[str, str]]) -> None:
        """``status()`` names the processes ``teleprog up`` started and how each is."""
        with self._ctx.lock:
            self._children = status

    def _children_status(self) -> dict[str, str]:
        fn = self._children
        if fn is None:
            return {}
        try:
            return dict(fn())
        except Exception:  # noqa: BLE001 - the link view must always answer
            log.exception("reading the children's status failed")
            return {"children": "status unknown"}

    def _round_trip(self) -> float | None:
        """The median of the last five measured round trips (``statistics`` gives numpy's median
        of five floats in a microsecond, not twenty). The slice is one copy, taken whole, so no
        lock is needed."""
        trips = self._dispatch.round_trips[-5:]
        return float(statistics.median(trips)) if trips else None

    def telemetry_age_s(self) -> float | None:
        """``view().telemetry_age_s`` alone (the remote arm's view needs only this): since the
        newest frame arrived, plus the one-way delay (read without the session's lock, as the view is)."""
        rtt = self._round_trip()
        newest = self._remote.newest()
        if newest is None:
            return None
        return self._ctx.clock() - newest[1] + (rtt / 2 if rtt is not None else 0.0)

    def view(self, *, address: bool = False) -> LinkView:
        """The link now. The robot's address only with ``address`` (``GET /api/link`` to the
        holder of control): everything published, and every other caller, gets ``url`` None."""
        # read without the session's lock: a long computation holding it must not keep the
        # link's state (a STOP's acknowledgement, silence, the robot's state) from anyone. Each
        # read is one step: attributes set once, a slice, the mirror's newest (frame, time)
        # tuple, a copy of the pending dict.
        d = self._dispatch
        robot, url = d.robot, d.url
        rtt = self._round_trip()
        newest = self._remote.newest()
        frame, at = newest if newest is not None else (None, None)
        ago = self._ctx.clock() - at if at is not None else None
        recovery = list(self.recovery.pending.copy().values()) if self.recovery is not None else []
        configured = url is not None
        url = url if address else None
        delay = rtt / 2 if rtt is not None else None
        children = self._children_status()
        if robot is None:
            return LinkView(configured=configured, url=url, children=children,
                            problems=[f"{name} {what}" for name, what in children.items() if not what.startswith("running")])
        h = robot.health()
        fresh = frame is not None and h.telemetry == "live"
        return LinkView(
            configured=True, url=url, connected=h.connected,
            delay_s=delay, round_trip_s=rtt, telemetry_received_ago_s=ago,
            telemetry_age_s=None if ago is None else ago + (delay or 0.0),
            reconnects=robot.reconnects,
            robot_state=frame.state.name.lower() if fresh else None,
            recovery_pending=recovery, status=h.command, heard_ago_s=h.heard_ago_s, silence_limit_s=h.silence_limit_s,
            telemetry=h.telemetry, halted=h.halted, errors=h.errors, last_error=h.last_error, refused=h.refused,
            buffer_full=h.buffer_full, robot_session=h.session_id, robot_restarts=h.restarts, children=children,
            problems=link_problems(h, children), telemetry_frames=h.telemetry_frames, door=h.door,
        )

    def tick(self) -> None:
        """Publish the link view when ``link_poll_s`` has passed since the last time."""
        now = self._ctx.clock()
        if self._published_at is not None and now - self._published_at < self._ctx.settings.link_poll_s:
            return
        self._published_at = now
        try:
            self._ctx.bus.emit([LinkChanged(link=self.view())])
        except Exception:  # noqa: BLE001 - the timer must outlive any one bad view
            log.exception("publishing the link view failed")
