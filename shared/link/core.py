"""The delayed link between console and robot, as a pure state machine fed explicit timestamps.

The thesis's trials put 3 s of delay on each way of the line (§4.6). ``LinkCore`` models one
connection through such a line: messages go in with the time they were sent, deliveries come out
when their due time has passed. It owns no clock and no socket, so the same code runs in virtual
time in tests and under asyncio in ``server.relay.link_relay``.

Per message, in each direction:

* **bandwidth**: the line carries ``bandwidth_bytes_per_s``; a message starts transmitting when
  the line is free (``tx_start = max(sent, line_free)``) and occupies it for ``size / bandwidth``
  seconds, so bursts queue (0 means unlimited);
* **delay and jitter**: it arrives ``delay_s`` plus a seeded uniform draw in ``[0, jitter_s]``
  after its transmission ends. The set delay is a floor: the line is never faster than set;
* **order**: a message is never due before the one sent ahead of it on the same direction
  (``due = max(due, previous due)``), so jitter never reorders. Like TCP, which WebSockets run on;
* **faults**: with ``drop_probability`` a message is lost. On a stream transport a lost message
  means a broken connection, so the core then reports a ``LinkFault``, discards everything in
  flight both ways and refuses new connections for ``outage_s``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from enum import Enum

import numpy as np
from pydantic import BaseModel, ConfigDict, Field


class Direction(str, Enum):
    UP = "up"  # console -> robot (commands)
    DOWN = "down"  # robot -> console (answers, reports, telemetry)


class LinkParams(BaseModel):
    """How one link behaves; SI units (s, bytes/s)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    delay_s: float = Field(3.0, ge=0.0, le=600.0, description="delay each way, s (thesis §4.6: 3 s)")
    jitter_s: float = Field(0.0, ge=0.0, le=60.0, description="extra delay drawn uniformly in [0, jitter], s")
    bandwidth_bytes_per_s: float = Field(0.0, ge=0.0, description="line rate each way, bytes/s; 0: unlimited")
    drop_probability: float = Field(0.0, ge=0.0, lt=1.0, description="chance a message is lost (cuts the connection)")
    outage_s: float = Field(1.0, ge=0.0, le=3600.0, description="after a fault, time until reconnecting works, s")
    seed: int = Field(0, ge=0, description="seed of jitter and loss draws")


@dataclass(frozen=True)
class Delivery:
    direction: Direction
    payload: bytes | str
    index: int  # 0, 1, 2 ... per direction, in the order sent
    sent_at: float
    due_at: float


@dataclass(frozen=True)
class LinkFault:
    """The connection broke at ``at`` (message ``index`` of ``direction`` was lost)."""

    at: float
    direction: Direction
    index: int
    lost: int  # messages in flight discarded with it, both ways
    up_at: float  # when new connections are accepted again


@dataclass
class _InFlight:
    payload: bytes | str
    index: int
    sent_at: float
    due_at: float
    lost: bool


class _Line:
    """One direction: a FIFO whose due times never decrease."""

    def __init__(self, direction: Direction, params: LinkParams) -> None:
        self.direction = direction
        self.params = params
        salt = 0 if direction is Direction.UP else 1
        self._jitter_rng = np.random.default_rng([params.seed, salt, 0])
        self._loss_rng = np.random.default_rng([params.seed, salt, 1])
        self.queue: deque[_InFlight] = deque()
        self.losses: deque[_InFlight] = deque()  # the lost ones among queue, in order
        self.free_at = float("-inf")
        self.last_due = float("-inf")
        self.sent = 0

    def push(self, now: float, payload: bytes | str, size: int) -> _InFlight:
        p = self.params
        tx_start = max(now, self.free_at)
        tx_end = tx_start + (size / p.bandwidth_bytes_per_s if p.bandwidth_bytes_per_s > 0 else 0.0)
        self.free_at = tx_end
        jitter = float(self._jitter_rng.uniform(0.0, p.jitter_s)) if p.jitter_s > 0 else 0.0
        due = max(tx_end + p.delay_s + jitter, self.last_due)
        self.last_due = due
        lost = p.drop_probability > 0 and float(self._loss_rng.random()) < p.drop_probability
        item = _InFlight(payload, self.sent, now, due, lost)
        self.sent += 1
        self.queue.append(item)
        if lost:
            self.losses.append(item)
        return item

    def clear(self) -> int:
        n = len(self.queue)
        self.queue.clear()
        self.losses.clear()
        self.free_at = float("-inf")
        return n

    def queued_bytes(self) -> int:
        return sum(_size(i.payload) for i in self.queue)


def _size(payload: bytes | str) -> int:
    return len(payload.encode("utf-8")) if isinstance(payload, str) else len(payload)


class LinkCore:
    """One connection through a delayed line, both directions.

    Call ``send`` when a message enters, ``poll(now)`` to collect what is due, ``next_due`` to know
    when to poll next. Times are seconds on any monotonic clock the caller chooses.
    """

    def __init__(self, params: LinkParams | None = None) -> None:
        self.params = params or LinkParams()
        self._lines = {d: _Line(d, self.params) for d in Direction}
        self.down_until = float("-inf")
        self.delivered = {d: 0 for d in Direction}

    def send(self, now: float, direction: Direction, payload: bytes | str, size: int | None = None) -> float | None:
        """A message enters the line at ``now``; returns its due time (None while the link is down)."""
        if now < self.down_until:
            return None
        item = self._lines[direction].push(now, payload, _size(payload) if size is None else size)
        return item.due_at

    def next_due(self) -> float | None:
        """Earliest time at which ``poll`` has something to hand out."""
        # a lost message breaks the connection as soon as it is sent
        times = [line.queue[0].due_at for line in self._lines.values() if line.queue]
        times += [line.losses[0].sent_at for line in self._lines.values() if line.losses]
        return min(times, default=None)

    def poll(self, now: float) -> list[Delivery | LinkFault]:
        """Everything due by ``now``, in due order (ties: up before down)."""
        out: list[Delivery | LinkFault] = []
        up, down = self._lines[Direction.UP].queue, self._lines[Direction.DOWN].queue
        while True:
            fault = self._first_loss(now)
            candidates = [(q[0].due_at, i, q) for i, q in enumerate((up, down)) if q and q[0].due_at <= now]
            if fault is not None and (not candidates or fault[0] <= min(candidates)[0]):
                out.append(self._fault(*fault))
                return out
            if not candidates:
                return out
            _, i, q = min(candidates, key=lambda c: (c[0], c[1]))
            item = q.popleft()
            direction = Direction.UP if i == 0 else Direction.DOWN
            self.delivered[direction] += 1
            out.append(Delivery(direction, item.payload, item.index, item.sent_at, item.due_at))

    def _first_loss(self, now: float) -> tuple[float, Direction, int] | None:
        best = None
        for d, line in self._lines.items():
            if line.losses:
                item = line.losses[0]
                if item.sent_at <= now and (best is None or item.sent_at < best[0]):
                    best = (item.sent_at, d, item.index)
        return best

    def _fault(self, at: float, direction: Direction, index: int) -> LinkFault:
        lost = sum(line.clear() for line in self._lines.values())
        self.down_until = at + self.params.outage_s
        return LinkFault(at=at, direction=direction, index=index, lost=lost, up_at=self.down_until)

    def cut(self) -> int:
        """The connection ended from outside (an endpoint closed): discard what is in flight."""
        return sum(line.clear() for line in self._lines.values())

    def available(self, now: float) -> bool:
        """Whether a new connection may be opened at ``now`` (not within an outage)."""
        return now >= self.down_until

    def in_flight(self, direction: Direction | None = None) -> int:
        lines = self._lines.values() if direction is None else [self._lines[direction]]
        return sum(len(line.queue) for line in lines)

    def queued_bytes(self, direction: Direction) -> int:
        return self._lines[direction].queued_bytes()
