"""What every part of the console shares: the cell and robot, the settings, one re-entrant lock,
the event bus, the control lock and the clocks.

Threading: the parts' methods may be called from any thread (viser's handlers, uvicorn's worker
threads, the asyncio loop's callbacks). State changes happen under ``lock``, never held across an
``await`` or while listeners run; events are published after the lock is released.

The robot client's loop (``robot-io``) carries heartbeats and STOP: nothing on it may wait for
``lock`` or run a listener. A coroutine the console schedules there only awaits the robot; what
follows the robot's answer (bookkeeping under the lock, events) is posted to ``after``, a thread of
the console's own that runs those calls in order.

Clocks: ``clock`` is monotonic seconds (ages, rates, the generator's samples, the preview's
playing); ``wall_clock`` is Unix seconds (the ``*_at`` fields people read). Both are injected, so
tests run the console in virtual time.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from server.console.bus import EventBus
from server.delivery import Delivery
from shared.cells.cell import Cell
from shared.program.generator import GeneratorSettings
from shared.robots.jog import JogFrames

Clock = Callable[[], float]


@dataclass(frozen=True)
class SessionSettings:
    """Thresholds and rates of the session (SI)."""

    divergence_joint: float = float(np.radians(1.0))
    """rad: a joint differing more than this between virtual/predicted and reported arm diverges."""
    divergence_tool: float = 0.002
    """m: a tool point further than this from where it should be diverges."""
    locate_max_residual_px: float = 3.0
    """pixels: picked image points that reproject worse than this do not locate an object."""
    preview_dt: float = 0.05
    """s: spacing of the preview samples checked for collisions and joint limits."""
    preview_max_samples: int = 600
    player_rate_hz: float = 30.0
    """how often a playing preview is published."""
    remote_event_hz: float = 10.0
    """how often telemetry is published as a ``RemoteArmChanged`` event."""
    link_poll_s: float = 0.25
    """how often the link view is published (its ages grow even when nothing else changes)."""
    predicted_points: int = 60
    gripper_closed_below: float = 0.03
    """m: a reported gripper opening below this counts as holding."""
    back_away_distance: float = 0.03
    """m: how far "back away" moves the tool out of a contact."""
    back_away_speed: float = 0.01
    """m/s: the tool speed of a back-away motion."""
    generator: GeneratorSettings = field(default_factory=GeneratorSettings)
    auto_generate: bool = True
    """Automatic generation is on when the session starts: the first drag records statements."""
    handover_timeout_s: float = 30.0
    """s: a request for control the holder neither hands over nor refuses passes control after this."""
    strict_editing: bool = False
    """The program editor starts with the thesis's editing rules (§4.3.6) instead of free editing
    (``shared.program.editor``); the page and ``PUT /api/program/editing`` switch it."""


@dataclass
class ConsoleContext:
    """The shared ground of the console's parts (see the module docstring)."""

    cell: Cell
    settings: SessionSettings
    bus: EventBus
    clock: Clock = time.monotonic
    wall_clock: Clock = time.time
    lock: threading.RLock = field(default_factory=threading.RLock)
    after: Delivery = field(default_factory=lambda: Delivery(name="console-after"))
    """What follows a robot's answer, off the robot client's loop (module docstring)."""

    def __post_init__(self) -> None:
        self.robot = self.cell.robot
        self.frames = JogFrames(self.cell.world_T_base, self.cell.frame("work"), self.cell.flange_T_tcp)
