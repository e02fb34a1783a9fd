"""How late the web server's event loop wakes: a watch for stalls (issue 35).

A task asks to wake every ``period`` seconds and records how much later than asked it did: the
time the loop was busy with something else (a handler computing, a lock waited for on the loop).
``GET /api/health?loop=1`` reports the newest samples' median, 99th percentile and maximum and
the stalls over 50 ms; ``reset`` starts a new window (a benchmark's drag).
"""

from __future__ import annotations

import asyncio
import time
from collections import deque

import numpy as np
from pydantic import BaseModel, Field

STALL_S = 0.05


class LoopLag(BaseModel):
    samples: int = Field(description="wake-ups measured since the last reset (the newest 20,000 at most)")
    period_ms: float
    median_ms: float | None = None
    p99_ms: float | None = None
    max_ms: float | None = None
    stalls_over_50ms: int = 0


class LoopWatch:
    def __init__(self, period: float = 0.01, keep: int = 20_000) -> None:
        self.period = period
        self._lags: deque[float] = deque(maxlen=keep)
        self._stalls = 0

    async def run(self) -> None:
        while True:
            asked = time.perf_counter() + self.period
            await asyncio.sleep(self.period)
            lag = max(0.0, time.perf_counter() - asked)
            self._lags.append(lag)
            if lag > STALL_S:
                self._stalls += 1

    def reset(self) -> None:
        self._lags.clear()
        self._stalls = 0

    def view(self) -> LoopLag:
        lags = np.array(self._lags)
        if lags.size == 0:
            return LoopLag(samples=0, period_ms=1e3 * self.period)
        return LoopLag(samples=int(lags.size), period_ms=1e3 * self.period, median_ms=1e3 * float(np.median(lags)),
                       p99_ms=1e3 * float(np.percentile(lags, 99)), max_ms=1e3 * float(lags.max()),
                       stalls_over_50ms=self._stalls)
