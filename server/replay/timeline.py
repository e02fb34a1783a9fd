"""A recorded session as a timeline: what the console showed at any moment, and its events.

``Timeline(recording)`` indexes the recording's streams by time once; ``at(t_ns)`` answers what
the console showed then (the newest message of each stream at or before ``t_ns``): the virtual
arm, the remote arm's last frame and how old the state it showed was, the predicted path, the
sent list, the regime and the link. ``marks`` are the moments worth stepping to: each statement
status, each submitted range, regime and display changes, collisions starting and ending,
divergence, the operator's actions and notices, link status changes.

Times are the console's clock (Unix ns) as recorded; ``t_s`` counts from the recording's start.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import Any

from server.console.views import SentListView
from server.recording import records
from server.recording.reader import RecordedMessage, Recording

# event topics drawn continuously (not marks): every arm move, every frame, every tick
_CONTINUOUS = {"arm", "remote", "link", "readiness", "predicted", "preview", "collision", "program", "sent",
               "terrain", "placement", "divergence"}


@dataclass(frozen=True)
class Mark:
    """A moment worth stepping to."""

    t_ns: int
    kind: str
    """``status``, ``submitted``, ``regime``, ``collision``, ``divergence``, ``action``, ``notice``,
    ``link``, ``control``, ``display``, ``dropped``"""
    text: str


@dataclass(frozen=True)
class Moment:
    """What the console showed at ``t_ns``."""

    t_ns: int
    t_s: float
    """seconds since the recording's start"""
    virtual_q: list[float] | None
    world_T_tool: list[list[float]] | None
    object_poses: dict[str, list[list[float]]]
    remote_q: list[float] | None
    remote_state: str | None
    remote_statement: int | None
    remote_age_s: float | None
    """how old the state the ghost shows was then: since its frame arrived, plus the link's delay"""
    predicted: list[list[float]]
    """tool points of what was sent and not done, world m"""
    sent: SentListView | None
    regime: str | None
    link_status: str | None
    last_mark: Mark | None
    dropped: int = 0
    """messages the recorder had dropped by then"""


class _Stream:
    """One topic's messages with their times, for 'the newest at or before t'."""

    def __init__(self, messages: list[RecordedMessage]) -> None:
        self.times = [m.log_time_ns for m in messages]
        self.messages = messages

    def index(self, t_ns: int) -> int:
        return bisect.bisect_right(self.times, t_ns) - 1

    def last(self, t_ns: int) -> RecordedMessage | None:
        i = self.index(t_ns)
        return self.messages[i] if i >= 0 else None

    def last_or_first(self, t_ns: int) -> RecordedMessage | None:
        """For a state that held before its first message (the virtual arm as the session
        started: its first record follows the start by microseconds)."""
        i = self.index(t_ns)
        return self.messages[max(i, 0)] if self.messages else None

    def __len__(self) -> int:
        return len(self.messages)


@dataclass
class Timeline:
    recording: Recording
    marks: list[Mark] = field(init=False)

    def __post_init__(self) -> None:
        r = self.recording
        self.start = r.start_ns
        self.end = r.end_ns
        self.session = r.session
        self._virtual = _Stream(r.on(records.VIRTUAL_ARM))
        self._telemetry = _Stream(r.on(records.TELEMETRY))
        self._arm_events = _Stream(r.on(records.event_topic("arm")))
        self._predicted = _Stream(r.on(records.event_topic("predicted")))
        self._sent = _Stream(r.on(records.SENT))
        self._regime = _Stream(r.on(records.event_topic("regime")))
        self._link = _Stream(r.on(records.event_topic("link")))
        self._dropped = _Stream(r.on(records.DROPPED))
        self._sent_cache: dict[int, SentListView] = {}
        self.marks = _marks(r)
        self._mark_times = [m.t_ns for m in self.marks]

    @property
    def duration_s(self) -> float:
        return (self.end - self.start) * 1e-9

    def clamp(self, t_ns: int) -> int:
        return min(max(int(t_ns), self.start), self.end)

    def t_ns(self, t_s: float) -> int:
        """The console time ``t_s`` seconds after the start (clamped to the recording)."""
        return self.clamp(self.start + round(t_s * 1e9))

    # -- stepping ------------------------------------------------------------------------------
    def next_mark(self, t_ns: int) -> Mark | None:
        """The first mark after ``t_ns`` (None: none left)."""
        i = bisect.bisect_right(self._mark_times, t_ns)
        return self.marks[i] if i < len(self.marks) else None

    def previous_mark(self, t_ns: int) -> Mark | None:
        """The last mark before ``t_ns`` (None: none before)."""
        i = bisect.bisect_left(self._mark_times, t_ns) - 1
        return self.marks[i] if i >= 0 else None

    def mark_at(self, t_ns: int) -> Mark | None:
        i = bisect.bisect_right(self._mark_times, t_ns) - 1
        return self.marks[i] if i >= 0 else None

    # -- the picture at a moment ---------------------------------------------------------------
    def at(self, t_ns: int) -> Moment:
        t_ns = self.clamp(t_ns)
        virtual = self._virtual.last_or_first(t_ns)
        arm = self._arm_events.last_or_first(t_ns)
        frame = self._telemetry.last(t_ns)
        predicted = self._predicted.last(t_ns)
        regime = self._regime.last(t_ns)
        link = self._link.last(t_ns)
        dropped = self._dropped.last(t_ns)
        remote_age = None
        if frame is not None:
            delay = None
            if link is not None:
                delay = link.data.get("link", {}).get("delay_s")
            if delay is None and self.session is not None:
                delay = self.session.delay_s
            remote_age = (t_ns - frame.log_time_ns) * 1e-9 + (delay or 0.0)
        object_poses: dict[str, Any] = {}
        if arm is not None:
            object_poses = arm.data.get("arm", {}).get("object_poses", {}) or {}
        return Moment(
            t_ns=t_ns,
            t_s=(t_ns - self.start) * 1e-9,
            virtual_q=virtual.data["q"] if virtual is not None else None,
            world_T_tool=virtual.data["world_T_tool"] if virtual is not None else None,
            object_poses=object_poses,
            remote_q=frame.data["q"] if frame is not None else None,
            remote_state=frame.data["state"] if frame is not None else None,
            remote_statement=frame.data["statement"] if frame is not None else None,
            remote_age_s=remote_age,
            predicted=predicted.data.get("predicted", {}).get("points", []) if predicted is not None else [],
            sent=self._sent_view(t_ns),
            regime=regime.data.get("regime", {}).get("regime") if regime is not None else None,
            link_status=link.data.get("link", {}).get("status") if link is not None else None,
            last_mark=self.mark_at(t_ns),
            dropped=dropped.data.get("total", 0) if dropped is not None else 0,
        )

    def _sent_view(self, t_ns: int) -> SentListView | None:
        i = self._sent.index(t_ns)
        if i < 0:
            return None
        view = self._sent_cache.get(i)
        if view is None:
            view = self._sent_cache[i] = SentListView.model_validate(self._sent.messages[i].data)
        return view


def _marks(recording: Recording) -> list[Mark]:
    """The moments worth stepping to, in time order (see the module docstring)."""
    out: list[Mark] = []
    for m in recording.on(records.STATUS):
        s = m.data
        number = f"#{s['number']}" if s.get("number") is not None else f"(id {s['id']})"
        reason = f": {s['reason']}" if s.get("reason") else ""
        out.append(Mark(m.log_time_ns, "status", f"{number} {s['text']}: {s['status']}{reason}"))
    for m in recording.on(records.SUBMITTED):
        texts = m.data.get("texts", [])
        out.append(Mark(m.log_time_ns, "submitted", f"submitted {len(texts)}: " + "; ".join(texts)))
    for m in recording.on(records.DROPPED):
        out.append(Mark(m.log_time_ns, "dropped", f"the recorder dropped {m.data.get('count', 0)} messages"))
    was_colliding: bool | None = None
    for m in recording.on(records.event_topic("collision")):
        c = m.data.get("collision", {})
        colliding = bool(c.get("colliding"))
        if was_colliding is not None and colliding != was_colliding:
            pairs = ", ".join(f"{a} / {b}" for a, b in c.get("pairs", [])[:3])
            out.append(Mark(m.log_time_ns, "collision", f"collision: {pairs}" if colliding else "collision cleared"))
        was_colliding = colliding
    was_diverged: bool | None = None
    for m in recording.on(records.event_topic("divergence")):
        d = m.data.get("divergence", {})
        diverged = bool(d.get("diverged"))
        if diverged != bool(was_diverged):
            out.append(Mark(m.log_time_ns, "divergence", d.get("message") or ("diverged" if diverged else "back in step")))
        was_diverged = diverged
    last_status: str | None = None
    for m in recording.on(records.event_topic("link")):
        status = m.data.get("link", {}).get("status")
        if status != last_status:
            out.append(Mark(m.log_time_ns, "link", f"link {status}"))
            last_status = status
    for topic in recording.topics:
        if not topic.startswith(records.EVENTS):
            continue
        kind = topic[len(records.EVENTS):]
        if kind in _CONTINUOUS and kind != "regime":
            continue
        for m in recording.on(topic):
            out.append(Mark(m.log_time_ns, kind, _event_text(kind, m.data)))
    out.sort(key=lambda mark: mark.t_ns)
    return out


def _event_text(kind: str, data: dict) -> str:
    if kind == "regime":
        r = data.get("regime", {})
        return f"regime {r.get('regime')} (zone {r.get('zone')})"
    if kind == "notice":
        return f"{data.get('level', 'info')}: {data.get('message', '')}"
    if kind == "action":
        what = data.get("action") or data.get("name") or "action"
        detail = data.get("detail") or data.get("message") or ""
        return f"operator: {what}" + (f" ({detail})" if detail else "")
    if kind == "display":
        return f"display {data.get('display')}"
    if kind == "control":
        c = data.get("control", {})
        holder = c.get("holder") or "nobody"
        return f"control: {holder}"
    return kind
