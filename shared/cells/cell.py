"""Workcells as data: a robot placed in a world with named objects, frames and features.

A cell file (TOML) names its robot and where it stands (``world_T_base``), its frames
(``world``, ``base``, ``work`` and any others), its objects (one or more primitive or mesh
shapes each, a pose in a named frame, whether the robot may pick it up), named features
(points such as holes, for task calls) and the control-zone distances of thesis section 4.2.1.
Everything here is in SI units; the loader converts the file's declared units once.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shared.cells.physics import PhysicsParams
from shared.robots.description import LinkShape
from shared.robots.model import Robot
from shared.vision.camera import Camera


@dataclass(frozen=True)
class CellObject:
    """A rigid object of the cell: ``world_T_object`` (4, 4) and its shapes in its own frame."""

    name: str
    world_T_object: np.ndarray
    shapes: tuple[LinkShape, ...]
    movable: bool = False
    held: bool = False  # starts in the gripper (pose then relative to the tool point)
    color: tuple[int, int, int] = (180, 180, 180)
    keypoints: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Feature points (n, 3) in the object's frame that a camera can find (thesis §4.2.3)."""


@dataclass(frozen=True)
class Feature:
    """A named point with an approach direction, e.g. a hole's mouth: ``world_T_feature``."""

    name: str
    world_T_feature: np.ndarray
    kind: str = "point"


@dataclass(frozen=True)
class ZoneDistances:
    """Control-zone boundaries (m) measured from the tool to the nearest object (section 4.2.1).

    distance > ``quasi``: free-motion zone; ``operation`` < distance <= ``quasi``:
    quasi-operation zone; distance <= ``operation``: operation zone.
    """

    quasi: float = 0.10
    operation: float = 0.02


@dataclass(frozen=True)
class Cell:
    """A loaded workcell. Immutable; per-user state (joint vectors, held objects) lives elsewhere."""

    name: str
    source: str
    robot: Robot
    world_T_base: np.ndarray
    q_home: np.ndarray
    flange_T_tcp: np.ndarray
    frames: dict[str, np.ndarray]  # name -> world_T_frame; always has world, base, work
    objects: tuple[CellObject, ...]
    features: dict[str, Feature] = field(default_factory=dict)
    zones: ZoneDistances = ZoneDistances()
    zone_overrides: dict[str, ZoneDistances] = field(default_factory=dict)
    description: str = ""
    cameras: dict[str, Camera] = field(default_factory=dict)
    physics: PhysicsParams = PhysicsParams()
    """The telerobot's contact physics (the file's ``[physics]`` table; defaults that run)."""

    @property
    def object_names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.objects)

    def object(self, name: str) -> CellObject:
        for o in self.objects:
            if o.name == name:
                return o
        from shared.errors import UnknownNameError

        raise UnknownNameError("object", name, self.object_names)

    def frame(self, name: str) -> np.ndarray:
        """``world_T_frame`` of a fixed named frame (world, base, work, ...)."""
        try:
            return self.frames[name]
        except KeyError:
            from shared.errors import UnknownNameError

            raise UnknownNameError("frame", name, self.frames) from None

    def zone_distances(self, object_name: str) -> ZoneDistances:
        return self.zone_overrides.get(object_name, self.zones)
