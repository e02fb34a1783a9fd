"""Long work the console runs off its loop, and how people see it under way.

A program file's load (parse, check, plan, format) and the task monitor's replay of a previewed or
submitted range can take seconds on a long program. They run on worker threads (the loop keeps
answering, the link's heartbeats never wait for them); this module tells the operator and the API
clients they are under way: a ``WorkProgress`` event on the bus (``/api/events``, the page's
progress bar under STOP), first once the work has run ``SHOW_AFTER_S``, then at most every
``EVERY_S``, and a last one, ``finished``, when it ends. Work shorter than ``SHOW_AFTER_S`` says
nothing (no flash of a bar for a one-line file).

Progress is phased: a work names its phases with their shares of the whole (measured on a
20,000-line file: planning is most of a load), and each phase reports how many of its items are
done; the fraction is the phases done plus the running phase's part of its share.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence

from server.console.bus import EventBus
from server.console.events import WorkKind, WorkProgress

SHOW_AFTER_S = 0.3
"""Work that ends sooner than this is not shown."""
EVERY_S = 0.2
"""At most this often a running work's progress is published."""

_ids = itertools.count(1)


class Work:
    """One run of a long work (used from the thread that does it); a context manager that
    publishes ``finished`` when it ends, however it ends."""

    def __init__(self, bus: EventBus, clock: Callable[[], float], kind: WorkKind, what: str,
                 phases: Sequence[tuple[str, float]]) -> None:
        if not phases:
            raise ValueError("a work has at least one phase")
        total = sum(share for _, share in phases)
        self._bus, self._clock = bus, clock
        self.id = next(_ids)
        self.kind, self.what = kind, what
        self._phases = [(name, share / total) for name, share in phases]
        self._index = 0
        self._done_share = 0.0  # the shares of the phases before the running one
        self._items = 1
        self._done = 0
        self._started = clock()
        self._last: float | None = None  # when progress was last published

    @property
    def fraction(self) -> float:
        share = self._phases[self._index][1]
        return min(1.0, self._done_share + share * min(1.0, self._done / max(1, self._items)))

    def phase(self, name: str, items: int) -> Callable[[int], None]:
        """Enter phase ``name`` (one of the phases given, in order) of ``items`` items; the
        function returned reports how many are done."""
        names = [n for n, _ in self._phases]
        if name not in names[self._index:]:
            raise ValueError(f"phase {name!r} is not one of {names[self._index:]}")
        while self._phases[self._index][0] != name:
            self._done_share += self._phases[self._index][1]
            self._index += 1
        self._items = max(1, int(items))
        self.advance(0)
        return self.advance

    def advance(self, done: int, items: int | None = None) -> None:
        """``done`` items of the running phase are done (of ``items``, when the phase learns its
        length only as it goes)."""
        if items is not None:
            self._items = max(1, int(items))
        self._done = done
        now = self._clock()
        if now - self._started >= SHOW_AFTER_S and (self._last is None or now - self._last >= EVERY_S):
            self._publish(now)

    def _publish(self, now: float, finished: bool = False) -> None:
        self._last = now
        self._bus.emit([WorkProgress(
            id=self.id, work=self.kind, what=self.what, phase=self._phases[self._index][0],
            fraction=1.0 if finished else round(self.fraction, 4), elapsed_s=round(now - self._started, 3),
            finished=finished)])

    def finish(self) -> None:
        if self._last is not None:  # never shown: nothing to close
            self._publish(self._clock(), finished=True)

    def __enter__(self) -> "Work":
        return self

    def __exit__(self, *exc) -> None:
        self.finish()
