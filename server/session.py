"""The console's session state: the virtual robot the operator drives.

One ``Session`` per console process. Every mutation happens under one lock (never held across
an ``await``) and every change is published to subscribers (the 3D scene, API watchers) after
the lock is released. Callers on any thread (viser's pool, uvicorn's workers) may call it.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from shared.cells.cell import Cell
from shared.robots.jog import JogFrames, JogResult, jog_joint, jog_tool, jog_tool_to, world_T_tcp

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class VirtualState:
    """A snapshot of the virtual robot: joint vector (rad), tool point pose in the world, and
    the last jog's outcome."""

    q: np.ndarray
    world_T_tcp: np.ndarray
    last_jog: JogResult | None = None
    version: int = 0


Listener = Callable[[VirtualState], None]


@dataclass
class _Listeners:
    items: list[Listener] = field(default_factory=list)


class Session:
    def __init__(self, cell: Cell) -> None:
        self.cell = cell
        self.robot = cell.robot
        self.frames = JogFrames(cell.world_T_base, cell.frame("work"), cell.flange_T_tcp)
        self._lock = threading.Lock()
        self._listeners = _Listeners()
        q0 = cell.q_home.copy()
        self._state = VirtualState(q0, world_T_tcp(self.robot, q0, self.frames))

    # -- reading ----------------------------------------------------------------------------
    @property
    def state(self) -> VirtualState:
        with self._lock:
            return self._state

    def subscribe(self, listener: Listener) -> None:
        with self._lock:
            self._listeners.items.append(listener)

    # -- writing ----------------------------------------------------------------------------
    def _apply(self, step: Callable[[np.ndarray], JogResult | np.ndarray]) -> VirtualState:
        """Compute the next joint vector from the current one and publish it, atomically: two
        callers on different threads never lose each other's step."""
        with self._lock:
            out = step(self._state.q)
            result = out if isinstance(out, JogResult) else None
            q = out.q if isinstance(out, JogResult) else out
            self._state = VirtualState(
                q.copy(), world_T_tcp(self.robot, q, self.frames), result, self._state.version + 1
            )
            state, listeners = self._state, list(self._listeners.items)
        for listener in listeners:
            try:
                listener(state)
            except Exception:  # a broken view must not break the session
                log.exception("session listener failed")
        return state

    def set_q(self, q: np.ndarray) -> VirtualState:
        """Put the virtual robot at ``q`` (checked against the joint ranges)."""
        q = self.robot.as_q(q)
        self.robot.check_limits(q)
        return self._apply(lambda _: q)

    def jog_joint(self, joint: int, delta: float) -> VirtualState:
        return self._apply(lambda q: jog_joint(self.robot, q, joint, delta))

    def set_joint(self, joint: int, value: float) -> VirtualState:
        """Turn joint ``joint`` (1-based) to ``value`` rad, stopping at its limit."""
        return self._apply(lambda q: jog_joint(self.robot, q, joint, value - q[joint - 1] if 1 <= joint <= len(q) else 0.0))

    def jog_tool(self, *, frame: str, constraint: str, motion: str, displacement: np.ndarray) -> VirtualState:
        return self._apply(
            lambda q: jog_tool(
                self.robot, q, frames=self.frames, frame=frame, constraint=constraint,
                motion=motion, displacement=displacement,
            )
        )

    def jog_tool_to(self, world_T_goal: np.ndarray, *, frame: str, constraint: str, motion: str) -> VirtualState:
        return self._apply(
            lambda q: jog_tool_to(
                self.robot, q, world_T_goal, frames=self.frames, frame=frame, constraint=constraint, motion=motion
            )
        )
