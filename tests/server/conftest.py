"""Fixtures of the console-session tests: the default cell with its collision model (built once
per module: it takes seconds) and a fresh session on it per test, in virtual time (``clock``)."""

from __future__ import annotations

import asyncio
import threading

import pytest

from server.console import Session
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel


LOOP_WAIT_S = 10.0


@pytest.fixture(scope="module")
def cell_and_scene():
    cell = load_cell(DEFAULT_CELL)
    return cell, SceneModel.from_cell(cell)


@pytest.fixture
def loop():
    """An event loop in a thread of its own, where a fake robot's coroutines run as the real
    client's would; what a test started there finishes before the loop closes."""
    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_forever, name="fake-robot-loop", daemon=True)
    thread.start()
    yield loop

    async def drain() -> None:
        others = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        if others:
            await asyncio.wait(others, timeout=LOOP_WAIT_S)

    asyncio.run_coroutine_threadsafe(drain(), loop).result(LOOP_WAIT_S + 1)
    loop.call_soon_threadsafe(loop.stop)
    thread.join(LOOP_WAIT_S)
    loop.close()


class ManualClock:
    """Virtual time for the session: it moves only when a test advances it."""

    def __init__(self, t: float = 1000.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t

    def advance(self, seconds: float) -> None:
        self.t += seconds


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock()


@pytest.fixture
def session(cell_and_scene, clock):
    cell, scene = cell_and_scene
    s = Session(cell, scene=scene, clock=clock, wall_clock=clock)
    yield s
    s.close()
