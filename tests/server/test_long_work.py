"""Long work off the console's loop tells people it is under way: a program file's load and the
task's replay publish ``WorkProgress`` (phases in order, a fraction that grows, a last event when it
ends), nothing for short work, and a load holds the session's lock only to put the program in place."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from server.console import Session, WorkProgress
from server.console import work as work_module
from server.console.bus import EventBus
from server.console.work import EVERY_S, SHOW_AFTER_S, Work
from shared.cells.loader import DEFAULT_CELL, load_cell


class SteppingClock:
    """Every reading is ``step`` seconds after the last one (work that takes time to read)."""

    def __init__(self, step: float) -> None:
        self.t, self.step = 0.0, step

    def __call__(self) -> float:
        self.t += self.step
        return self.t


def _collect(bus: EventBus) -> list[WorkProgress]:
    seen: list[WorkProgress] = []
    bus.subscribe(lambda e: seen.append(e) if isinstance(e, WorkProgress) else None)
    return seen


def test_work_shorter_than_the_threshold_says_nothing() -> None:
    bus = EventBus()
    seen = _collect(bus)
    with Work(bus, SteppingClock(0.001), "load", "loading a.tp", (("parse", 1.0),)) as work:
        step = work.phase("parse", 100)
        for i in range(100):
            step(i)
    assert seen == []


def test_long_work_reports_its_phases_in_order_at_a_bounded_rate_and_ends() -> None:
    bus = EventBus()
    seen = _collect(bus)
    clock = SteppingClock(0.01)
    with Work(bus, clock, "load", "loading big.tp", (("parse", 1.0), ("plan", 3.0))) as work:
        for phase, n in (("parse", 100), ("plan", 300)):
            step = work.phase(phase, n)
            for i in range(n):
                step(i)
    assert seen, "4 s of work is shown"
    assert seen[-1].finished and seen[-1].fraction == 1.0
    running = seen[:-1]
    assert all(not e.finished for e in running) and len({e.id for e in seen}) == 1
    assert running[0].elapsed_s >= SHOW_AFTER_S
    assert [e.phase for e in running] == sorted((e.phase for e in running), key=["parse", "plan"].index)
    fractions = [e.fraction for e in running]
    assert fractions == sorted(fractions) and 0.0 < fractions[0] < fractions[-1] < 1.0
    plan = [e for e in running if e.phase == "plan"]
    assert plan[0].fraction >= 0.25 - 1e-9  # parse is a quarter of the whole
    gaps = np.diff([e.elapsed_s for e in running])
    assert np.all(gaps >= EVERY_S - 0.011)  # never more often than EVERY_S (one clock step of slack)
    with pytest.raises(ValueError, match="phase"):
        Work(bus, clock, "load", "x", (("parse", 1.0),)).phase("plan", 1)


@pytest.fixture
def show_everything(monkeypatch):
    """Every progress report published (the thresholds are the unit test's business)."""
    monkeypatch.setattr(work_module, "SHOW_AFTER_S", 0.0)
    monkeypatch.setattr(work_module, "EVERY_S", 0.0)


def test_a_long_load_is_shown_under_way_and_plans_without_the_sessions_lock(show_everything) -> None:
    cell = load_cell(DEFAULT_CELL)
    session = Session(cell)
    try:
        seen: list[WorkProgress] = []
        lock_free_while_planning: list[bool] = []

        def listener(event) -> None:
            if not isinstance(event, WorkProgress):
                return
            seen.append(event)
            if event.phase == "plan" and not lock_free_while_planning:
                taken = []  # another thread (a jog, a page's click) takes the lock meanwhile

                def take() -> None:
                    got = session._ctx.lock.acquire(timeout=5.0)
                    if got:
                        session._ctx.lock.release()
                    taken.append(got)

                t = threading.Thread(target=take)
                t.start()
                t.join()
                lock_free_while_planning.append(taken[0])

        session.subscribe_events(listener)
        text = "\n".join(f"DRIVE J1 TO {(-1) ** i * 0.5:.1f} deg" for i in range(3000)) + "\n"
        view = session.program.load(text, "big.tp")
        assert len(view.entries) == 3001 and all(e.duration_s for e in view.entries[:-1])
        assert [e.phase for e in seen if not e.finished][0] == "parse"
        assert {"parse", "check", "plan", "format"} <= {e.phase for e in seen}
        assert seen[-1].finished and seen[-1].work == "load" and seen[-1].what == "loading big.tp"
        assert lock_free_while_planning == [True]
        assert session.program.durations() == [e.duration_s for e in view.entries[:-1]]  # the load's plan is kept
    finally:
        session.close()


def test_a_broken_long_file_ends_its_progress_too(show_everything) -> None:
    session = Session(load_cell(DEFAULT_CELL))
    try:
        seen: list[WorkProgress] = []
        session.subscribe_events(lambda e: seen.append(e) if isinstance(e, WorkProgress) else None)
        text = "\n".join(f"DRIVE J1 TO {(-1) ** i * 0.5:.1f} deg" for i in range(3000)) + "\nDRIVE J1 TO banana deg\n"
        with pytest.raises(Exception, match="3001"):
            session.program.load(text, "broken.tp")
        assert seen and seen[-1].finished
        assert session.program.state.statements == ()  # nothing of the broken file was taken
    finally:
        session.close()
