"""The kinematic world (``--world kinematic``): the analytic stand-in for the real cell, kept for
unit tests of the executor that need its speed. The telerobot's world is the physics world
(``robot_sim.physics``); this one has no dynamics, never jams and never sticks.

The robot lives in a world where the movable objects and the holes sit a little elsewhere (seeded
offsets) and the force sensor is noisy.

Contact model. The arm is position-controlled. Contact of the held object (or the bare gripper)
with the cell is modelled as a stiff spring: the force is ``contact_stiffness`` times how far the
commanded position has pushed past the surface. For the square peg and the plate the surface is
analytic (plate top, hole floors, hole walls with a chamfer that captures the peg when it is
within ``chamfer`` of the hole axis): that is the precision the task needs (0.03 mm clearance)
and a mesh query cannot give penetration depth. Unplanned contact anywhere else (arm against the
table, gripper against the plate) is found by the collision core on the true object poses.

Everything is in SI units in the world frame. The world has no clock: the executor advances it.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from shared.cells.cell import Cell
from shared.robots.model import Robot
from shared.spatial import invert, matrix_to_rpy
from shared.wire.messages import ObjectPose
from robot_sim.settings import WorldSettings

log = logging.getLogger(__name__)


def perceived_poses(pegs: dict[str, PegState], world_T_base: np.ndarray) -> tuple[ObjectPose, ...]:
    """Each object's true pose in the robot's base frame, as the robot reports it (either world)."""
    base_T_world = invert(world_T_base)
    out = []
    for name, peg in pegs.items():
        base_T_peg = base_T_world @ peg.world_T_peg
        out.append(ObjectPose(name=name, base_p=tuple(float(v) for v in base_T_peg[:3, 3]),
                              base_rpy=tuple(float(v) for v in matrix_to_rpy(base_T_peg[:3, :3]))))
    return tuple(out)


@dataclass(frozen=True)
class Contact:
    """What the force sensor feels now: force on the tool in the world frame (N)."""

    force: np.ndarray  # (3,)
    touching: bool
    what: str = ""  # name of the surface touched, for reports

    @property
    def magnitude(self) -> float:
        f = self.force
        return math.sqrt(float(f @ f))


@dataclass
class PegState:
    """The square peg: in a hole (by name), in the gripper, or lying at a free pose."""

    world_T_peg: np.ndarray
    half_size: np.ndarray  # (3,) half extents in the peg frame
    in_hole: str | None = None
    held: bool = False
    tool_T_peg: np.ndarray | None = None


@dataclass
class Hole:
    name: str
    world_T_hole: np.ndarray  # mouth centre, z up out of the hole
    depth: float


@dataclass
class SimWorld:
    """The real cell around the telerobot: true poses, the gripper, the contact model."""

    cell: Cell
    robot: Robot
    settings: WorldSettings = field(default_factory=WorldSettings)
    holes: dict[str, Hole] = field(init=False)
    pegs: dict[str, PegState] = field(init=False)
    plate_top_z: float = field(init=False)
    table_top_z: float = field(init=False)
    gripper_closed: bool = field(init=False, default=False)

    def __post_init__(self) -> None:
        rng = np.random.default_rng(self.settings.seed)
        off = self.settings.object_offset

        def jitter() -> np.ndarray:
            return np.array([*rng.uniform(-off, off, 2), 0.0])

        self.holes = {}
        for feat in self.cell.features.values():
            if feat.kind != "hole":
                continue
            T = feat.world_T_feature.copy()
            T[:3, 3] += jitter()
            self.holes[feat.name] = Hole(feat.name, T, depth=self.settings.hole_depth)
        self.pegs = {}
        for obj in self.cell.objects:
            if not obj.movable:
                continue
            T = obj.world_T_object.copy()
            half = np.asarray(obj.shapes[0].size, dtype=float) / 2.0
            peg = PegState(world_T_peg=T, half_size=half)
            # a peg standing in a hole of the model stands in the same hole of the real world
            for hole in self.holes.values():
                model_mouth = self._model_feature(hole.name)[:3, 3]
                if np.linalg.norm(T[:2, 3] - model_mouth[:2]) < 1e-6:
                    peg.in_hole = hole.name
                    T[:3, 3] += hole.world_T_hole[:3, 3] - model_mouth
            self.pegs[obj.name] = peg
        self.plate_top_z = self._top_of("plate", default=-np.inf)
        self._plate_half = self._half_extent_xy("plate")
        self.table_top_z = self._top_of("table", default=-np.inf)
        self._rng = rng

    # -- model lookups ----------------------------------------------------------------------
    def _half_extent_xy(self, name: str) -> np.ndarray:
        """Half extents in x and y, in the object's frame, of all its shapes together."""
        for obj in self.cell.objects:
            if obj.name == name:
                half = np.zeros(2)
                for s in obj.shapes:
                    extent = np.abs(s.link_T_shape[:3, :3]) @ (np.asarray(s.size, dtype=float) / 2.0)
                    half = np.maximum(half, np.abs(s.link_T_shape[:2, 3]) + extent[:2])
                return half
        return np.zeros(2)

    def _model_feature(self, name: str) -> np.ndarray:
        return self.cell.features[name].world_T_feature

    def _top_of(self, name: str, default: float) -> float:
        for obj in self.cell.objects:
            if obj.name == name:
                tops = []
                for s in obj.shapes:
                    T = obj.world_T_object @ s.link_T_shape
                    half = np.abs(T[:3, :3]) @ (np.asarray(s.size, dtype=float) / 2.0)
                    tops.append(T[2, 3] + half[2])
                return float(max(tops))
        return default

    # -- kinematics in the world -------------------------------------------------------------
    def world_T_tcp(self, q: np.ndarray) -> np.ndarray:
        return self.cell.world_T_base @ self.robot.fk(q) @ self.cell.flange_T_tcp

    def held_peg(self) -> tuple[str, PegState] | None:
        for name, peg in self.pegs.items():
            if peg.held:
                return name, peg
        return None

    # -- the gripper ---------------------------------------------------------------------------
    def grasp(self, q: np.ndarray, name: str | None = None) -> tuple[bool, str]:
        """Close the gripper; it holds a peg when the fingers' centre is on the peg's axis (within
        ``grasp_tolerance``) and along the peg between 10 mm above its foot and 5 mm below its top.

        Returns (holding, a sentence for the report).
        """
        self.gripper_closed = True
        world_T_tcp = self.world_T_tcp(q)
        best: tuple[float, str] | None = None
        for peg_name, peg in self.pegs.items():
            if name is not None and peg_name != name:
                continue
            peg_p_tcp = np.linalg.inv(peg.world_T_peg) @ world_T_tcp[:, 3]
            along = float(np.clip(peg_p_tcp[2], -peg.half_size[2] + 0.010, peg.half_size[2] - 0.005))
            d = float(np.hypot(np.hypot(peg_p_tcp[0], peg_p_tcp[1]), peg_p_tcp[2] - along))
            if best is None or d < best[0]:
                best = (d, peg_name)
        if best is None or best[0] > self.settings.grasp_tolerance:
            where = f"{best[0] * 1e3:.1f} mm from where {best[1]} can be held" if best else "no object to grasp"
            return False, f"gripper closed on nothing ({where})"
        peg = self.pegs[best[1]]
        peg.held = True
        peg.tool_T_peg = np.linalg.inv(world_T_tcp) @ peg.world_T_peg
        return True, f"holding {best[1]} ({best[0] * 1e3:.2f} mm off its axis)"

    def release(self, q: np.ndarray) -> str:
        """Open the gripper; a held peg stays where it is (in a hole if its foot is in one)."""
        self.gripper_closed = False
        held = self.held_peg()
        if held is None:
            return "gripper opened, holding nothing"
        name, peg = held
        self.follow(q)
        peg.held = False
        peg.tool_T_peg = None
        hole = self._hole_under(peg, capture=self.settings.chamfer)
        foot_z = peg.world_T_peg[2, 3] - peg.half_size[2]
        if hole is not None and foot_z < hole.world_T_hole[2, 3]:
            peg.in_hole = hole.name
            return f"released {name} in {hole.name}"
        peg.in_hole = None
        return f"released {name}"

    def follow(self, q: np.ndarray) -> None:
        """Carry a held peg with the tool."""
        held = self.held_peg()
        if held is not None:
            name, peg = held
            peg.world_T_peg = self.world_T_tcp(q) @ peg.tool_T_peg
            if peg.in_hole is not None:
                hole = self.holes[peg.in_hole]
                if peg.world_T_peg[2, 3] - peg.half_size[2] > hole.world_T_hole[2, 3]:
                    peg.in_hole = None  # pulled clear of the hole

    def perceived_objects(self) -> tuple[ObjectPose, ...]:
        """The movable objects where the robot's sensing puts them, in its base frame. The
        simulation reports the true poses (a real cell would see them through a camera, with
        its error): they differ from the console's model wherever the world does (holes off
        their modelled place, a peg seated by search)."""
        return perceived_poses(self.pegs, self.cell.world_T_base)

    # -- contact -------------------------------------------------------------------------------
    def _hole_under(self, peg: PegState, capture: float) -> Hole | None:
        foot = peg.world_T_peg[:3, 3]
        for hole in self.holes.values():
            offset = foot[:2] - hole.world_T_hole[:2, 3]
            if np.all(np.abs(offset) <= capture):
                return hole
        return None

    def contact(self, q: np.ndarray, noise: bool = True) -> Contact:
        """Force on the tool for the commanded joint vector ``q`` (sensor noise included unless
        ``noise`` is False: the contact itself, for comparing two poses).

        Only the held peg touches in this model (with the gripper empty the arm is in free space
        unless the collision core says otherwise, which the executor checks separately).
        """
        held = self.held_peg()
        if held is None:
            return Contact(self._noise() if noise else np.zeros(3), touching=False)
        name, peg = held
        world_T_peg = self.world_T_tcp(q) @ peg.tool_T_peg
        foot = world_T_peg[:3, 3] - world_T_peg[:3, 2] * peg.half_size[2]
        k = self.settings.contact_stiffness
        force = np.zeros(3)
        what = ""
        hole = None
        for h in self.holes.values():
            if np.all(np.abs(foot[:2] - h.world_T_hole[:2, 3]) <= self.settings.chamfer):
                hole = h
                break
        if hole is not None:
            floor = hole.world_T_hole[2, 3] - hole.depth
            if foot[2] < floor:
                force[2] += k * (floor - foot[2])
                what = f"{hole.name} floor"
        else:
            surface = self.plate_top_z if self._over_plate(foot) else self.table_top_z
            if foot[2] < surface:
                force[2] += k * (surface - foot[2])
                what = "plate top" if surface == self.plate_top_z else "table top"
        touching = bool(np.linalg.norm(force) > 0.0)
        return Contact(force + self._noise() if noise else force, touching=touching, what=what)

    def _over_plate(self, p: np.ndarray) -> bool:
        plate = next((o for o in self.cell.objects if o.name == "plate"), None)
        if plate is None:
            return False
        local = np.linalg.inv(plate.world_T_object) @ np.array([*p, 1.0])
        return bool(abs(local[0]) <= self._plate_half[0] and abs(local[1]) <= self._plate_half[1])

    def _noise(self) -> np.ndarray:
        sigma = self.settings.force_noise
        return self._rng.normal(0.0, sigma, 3) if sigma > 0 else np.zeros(3)
