"""The delayed link with a fault in it, for a campaign run in virtual time.

``FaultyLink`` wraps the run's ``LinkCore`` and keeps its interface (``send``, ``poll``,
``next_due``), so the virtual session does not know a fault is there:

- **stall** (the line or the link process frozen, or the console frozen): from ``start`` for
  ``duration`` nothing passes in the directions named; what is sent meanwhile waits and leaves
  when the stall ends, what was due waits at the far end and arrives then;
- **jitter burst**: for ``duration`` each message sent takes up to ``extra`` more on its way
  (seeded; the link's order is kept, as on TCP);
- **cut** (a lost message on a stream transport): at ``start`` everything in flight is lost, the
  robot sees its connection close, and the console connects again ``duration`` later (hello,
  welcome and the re-sending of whatever was not acknowledged, as a real console does).

(When the robot last received anything, the judge reads from the session: ``last_up_delivery``.)
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from shared.link.core import Delivery, Direction, LinkCore, LinkFault


class FaultyLink:
    def __init__(self, inner: LinkCore, *, kind: str, start: float, duration: float, extra: float = 0.0,
                 directions: tuple[Direction, ...] = (Direction.UP, Direction.DOWN), seed: int = 0,
                 on_cut: Callable[[], None] | None = None, on_reconnect: Callable[[], None] | None = None) -> None:
        self.inner = inner
        self.kind = kind
        self.start = start
        self.end = start + duration
        self.extra = extra
        self.directions = directions
        self._rng = np.random.default_rng((seed, 11))
        self._held: list[Delivery] = []
        self._on_cut = on_cut
        self._on_reconnect = on_reconnect
        self._cut_done = False
        self._reconnected = False
        self._now = -math.inf

    def _stalled(self, t: float, direction: Direction) -> bool:
        return self.kind == "stall" and self.start <= t < self.end and direction in self.directions

    def send(self, now: float, direction: Direction, payload: bytes | str, size: int | None = None) -> float | None:
        if self.kind == "cut" and self.start <= now < self.end:
            return None  # the connection is down: nothing goes out on it
        if self._stalled(now, direction):
            now = self.end  # waits in the sender's buffer until the stall ends
        elif self.kind == "jitter" and self.start <= now < self.end:
            now = now + float(self._rng.uniform(0.0, self.extra))
        return self.inner.send(now, direction, payload, size)

    def next_due(self) -> float | None:
        """The link's next delivery, or the fault's next edge (its start, its end) still ahead."""
        marks = [m for m in (self.inner.next_due(), *(e for e in (self.start, self.end) if e > self._now)) if m is not None]
        return min(marks, default=None)

    def poll(self, now: float) -> list[Delivery | LinkFault]:
        self._now = now
        out: list[Delivery | LinkFault] = []
        if self.kind == "cut" and now >= self.start and not self._cut_done:
            self._cut_done = True
            self.inner.cut()
            if self._on_cut is not None:
                self._on_cut()
        if self.kind == "cut" and now >= self.end and self._cut_done and not self._reconnected:
            self._reconnected = True
            if self._on_reconnect is not None:
                self._on_reconnect()
        if self._held and now >= self.end:
            out, self._held = self._held, []
        for item in self.inner.poll(now):
            if isinstance(item, Delivery) and self._stalled(now, item.direction):
                self._held.append(item)
            else:
                out.append(item)
        return out
