"""Which world the telerobot lives in: contact physics (the default) or the kinematic stand-in."""

from __future__ import annotations

from typing import TYPE_CHECKING

from robot_sim.settings import WorldSettings
from shared.cells.cell import Cell

if TYPE_CHECKING:
    from robot_sim.physics.world import PhysicsWorld
    from robot_sim.world import SimWorld


def make_world(cell: Cell, settings: WorldSettings | None = None, servo_period: float = 0.01) -> "PhysicsWorld | SimWorld":
    """The world ``settings.engine`` names, for ``cell``, seeded by ``settings.seed``."""
    settings = settings or WorldSettings()
    if settings.engine == "kinematic":
        from robot_sim.world import SimWorld

        return SimWorld(cell, cell.robot, settings)
    from robot_sim.physics.world import PhysicsWorld

    return PhysicsWorld(cell, cell.robot, settings, servo_period=servo_period)
