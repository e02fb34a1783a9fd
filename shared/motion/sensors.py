"""What the planner asks of the world when a statement says ``UNTIL``: a sensor model.

The preview passes a model of the cell, the telerobot passes its (simulated) sensors; the
planner only calls these two methods, with the time since the program started (s) and the joint
vector, so the same stop logic runs on both sides.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from shared.motion.frames import CellFrames
from shared.robots.model import Robot


@runtime_checkable
class SensorModel(Protocol):
    def force(self, t: float, q: np.ndarray) -> float:
        """Magnitude of the force on the tool (N)."""
        ...

    def contact(self, t: float, q: np.ndarray) -> bool:
        """Whether the tool touches something."""
        ...


class FreeSpace:
    """Nothing to touch: no force, no contact (an UNTIL FORCE/CONTACT motion runs to its end)."""

    def force(self, t: float, q: np.ndarray) -> float:
        return 0.0

    def contact(self, t: float, q: np.ndarray) -> bool:
        return False


@dataclass(frozen=True)
class PlaneSurface:
    """A rigid horizontal surface at world height ``height`` (m) seen through a spring:
    the tool centre point pressing ``d`` metres below it feels ``stiffness * d`` newtons, and is
    in contact from ``d >= 0``. A simple model of a table top for previewing guarded moves."""

    robot: Robot
    frames: CellFrames
    height: float
    stiffness: float = 2.0e4  # N/m

    def _depth(self, q: np.ndarray) -> float:
        return self.height - float(self.frames.world_T_tcp(self.robot, q)[2, 3])

    def force(self, t: float, q: np.ndarray) -> float:
        return self.stiffness * max(0.0, self._depth(q))

    def contact(self, t: float, q: np.ndarray) -> bool:
        return self._depth(q) >= 0.0
