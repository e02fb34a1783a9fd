"""The console's one event bus: typed ``SessionEvent``s for every watcher (the page's panels, the
``/api/events`` stream, a recorder), and the fast path of the virtual arm's state for the 3D
scene. A broken listener is logged and never breaks the session or the other listeners."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

from server.console.events import SessionEvent
from server.console.views import VirtualState
from shared.wire.telemetry import TelemetryFrame

log = logging.getLogger(__name__)

T = TypeVar("T")


class Listeners(Generic[T]):
    """A thread-safe list of callbacks of one argument."""

    def __init__(self, what: str) -> None:
        self._what = what
        self._lock = threading.Lock()
        self._listeners: list[Callable[[T], None]] = []

    def add(self, listener: Callable[[T], None]) -> Callable[[], None]:
        """Add ``listener``; returns a function that removes it."""
        with self._lock:
            self._listeners.append(listener)

        def remove() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)

        return remove

    def __len__(self) -> int:
        """How many listeners there are now (read without the lock: a snapshot)."""
        return len(self._listeners)

    def call(self, items: Sequence[T]) -> None:
        """Call every listener with each item, in order (never under the caller's locks)."""
        if not items or not self._listeners:  # nobody listens: not even the lock (50 Hz telemetry)
            return
        with self._lock:
            listeners = list(self._listeners)
        for item in items:
            for listener in listeners:
                try:
                    listener(item)
                except Exception:  # a broken watcher must not break the session
                    log.exception("%s listener failed", self._what)


class EventBus:
    """Typed session events, the virtual arm's fast path (every arm change) and every telemetry
    frame as it arrives (the events carry the remote arm at a lower rate)."""

    def __init__(self) -> None:
        self.events: Listeners[SessionEvent] = Listeners("session event")
        self.arm: Listeners[VirtualState] = Listeners("arm state")
        self.telemetry: Listeners[TelemetryFrame] = Listeners("telemetry frame")

    def emit(self, events: Sequence[SessionEvent]) -> None:
        self.events.call(events)

    def subscribe(self, listener: Callable[[SessionEvent], None]) -> Callable[[], None]:
        return self.events.add(listener)
