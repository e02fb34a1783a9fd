"""One thread that runs a robot client's listeners, in the order their messages arrived.

The robot client's asyncio loop moves bytes: heartbeats, STOP, the silence watches. What the
console does with a report or a telemetry frame (the session's lock, the task monitor's play of a
range, the scene's redraw) must never hold that loop up: a loop waiting on a lock sends no
heartbeat, and the robot halts itself after a second of silence. So the client hands each call to
:class:`Delivery`, whose one worker thread makes the calls one after another, and the loop goes on
at once.

Telemetry arrives 50 times a second; when the listeners fall behind by more than
``max_backlog`` frames, the oldest frames waiting are dropped (counted in ``dropped``), never a
report or anything else.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

log = logging.getLogger("teleprog.client")


@dataclass
class _Call:
    fn: Callable[..., None]
    args: tuple
    droppable: bool = False


@dataclass
class Delivery:
    """A FIFO of calls made on one daemon thread (started with the first call)."""

    name: str = "robot-listeners"
    max_backlog: int = 10  # frames (0.2 s at 50 Hz): a report never waits long behind stale telemetry
    on_error: Callable[[str, BaseException], None] | None = None
    dropped: int = 0
    _queue: deque[_Call] = field(default_factory=deque)
    _ready: threading.Condition = field(default_factory=threading.Condition)
    _thread: threading.Thread | None = None
    _closed: bool = False

    def post(self, fn: Callable[..., None], *args: object, droppable: bool = False) -> None:
        """Queue ``fn(*args)``; ``droppable`` calls (telemetry) may be dropped under backlog."""
        with self._ready:
            if self._closed:
                return
            self._queue.append(_Call(fn, args, droppable))
            if droppable and len(self._queue) > self.max_backlog:
                self._drop_oldest_droppable()
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
                self._thread.start()
            self._ready.notify()

    def _drop_oldest_droppable(self) -> None:
        for i, call in enumerate(self._queue):
            if call.droppable:
                del self._queue[i]
                self.dropped += 1
                if self.dropped == 1 or self.dropped % 500 == 0:
                    log.warning("the console's listeners fall behind the robot's telemetry: %d frame(s) dropped so far",
                                self.dropped)
                return

    def close(self) -> None:
        """Make no further calls (those still queued are dropped); the thread ends."""
        with self._ready:
            self._closed = True
            self._queue.clear()
            self._ready.notify()

    def _run(self) -> None:
        while True:
            with self._ready:
                while not self._queue and not self._closed:
                    self._ready.wait()
                if self._closed:
                    return
                call = self._queue.popleft()
            try:
                call.fn(*call.args)
            except Exception as exc:  # noqa: BLE001 - a listener must not end the delivery
                if self.on_error is not None:
                    self.on_error(getattr(call.fn, "__qualname__", repr(call.fn)), exc)
                else:
                    log.exception("a listener failed")
