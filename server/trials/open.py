"""Open one run's session on the clock asked for, as a :class:`server.trials.drivers.Driver`."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from robot_sim.settings import WorldSettings
from server.trials.drivers import ApiDriver, Clock, Driver


@contextmanager
def open_driver(clock: Clock, *, cell: str | Path, delay_ms: float, world: WorldSettings,
                log_path: Path) -> Iterator[Driver]:
    """``real``: a ``teleprog up`` session (its output in ``log_path``), the trial holding the
    control lock, the regime overridden to free (the trial's procedure decides when a statement
    is sent, as each mode defines); ``virtual``: console, link and robot in this process."""
    if clock == "virtual":
        from server.trials.virtual_clock import VirtualDriver

        driver = VirtualDriver(cell, world, delay_ms / 1e3)
        driver.wait_welcome()
        yield driver
        return
    from server.trials.session import TrialSession

    with TrialSession(delay_ms=delay_ms, cell=cell, world=world, log_path=log_path) as session:
        api = session.api
        api.take_control()
        api.call("PUT", "/api/regime", {"regime": "free"})
        yield ApiDriver(api, delay_ms / 1e3)
