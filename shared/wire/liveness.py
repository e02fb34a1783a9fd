"""Liveness on a delayed channel: heartbeats and the silence limit.

Each end of the command channel sends a ``heartbeat`` every ``HEARTBEAT_INTERVAL_S`` (and the
robot's telemetry flows at its frame rate). A steady delay shifts every arrival by the same amount,
so it never shows as silence: what counts is the gap between two arrivals. An end is *silent*
when nothing has arrived for longer than the expected gap plus the silence limit (a setting,
default 1 s). The robot answers silence with a controlled stop (``robot_sim.core``); the console
shows the link as silent, or its telemetry as stale, with the age (``server``).

``SilenceWatch`` is clock-free: callers pass the time (the executor's servo time on the robot,
the event loop's monotonic time on the console), so tests run it in virtual time.
"""

from __future__ import annotations

from dataclasses import dataclass

HEARTBEAT_INTERVAL_S = 0.2
"""How often each end of the command channel sends a heartbeat (s)."""
DEFAULT_SILENCE_LIMIT_S = 1.0
"""Silence tolerated beyond the expected arrival before an end calls the other silent (s)."""


@dataclass
class SilenceWatch:
    """When the other end was last heard, and whether it has been quiet for too long.

    ``interval`` is the expected gap between arrivals; ``limit`` the extra silence tolerated.
    Nothing is silent before the first arrival (``armed`` is False until then).
    """

    interval: float = HEARTBEAT_INTERVAL_S
    limit: float = DEFAULT_SILENCE_LIMIT_S
    last_heard: float | None = None

    def heard(self, now: float) -> None:
        self.last_heard = now

    def reset(self) -> None:
        """Forget the other end (a new connection starts unarmed)."""
        self.last_heard = None

    @property
    def armed(self) -> bool:
        return self.last_heard is not None

    @property
    def threshold(self) -> float:
        """Seconds without an arrival after which the other end is silent."""
        return self.interval + self.limit

    def age(self, now: float) -> float | None:
        """Seconds since the last arrival (None before the first)."""
        return None if self.last_heard is None else max(0.0, now - self.last_heard)

    def silent(self, now: float) -> bool:
        age = self.age(now)
        return age is not None and age > self.threshold
