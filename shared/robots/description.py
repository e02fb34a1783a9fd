"""Typed description of a robot as read from its file: kinematics, limits, link geometry.

A description is plain data (no pinocchio); ``shared.robots.model.Robot`` turns it into a
pinocchio model. All lengths are metres and all angles radians here: the loader converts the
file's declared units once.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

#: the default of ``RobotDescription.ik_limit_tolerance`` (rad): none, so that every solution
#: reaches its target exactly; a robot whose targets come printed to a rounding sets its own
IK_LIMIT_TOLERANCE = 0.0

DHConvention = Literal["modified", "standard"]
IKKind = Literal["puma", "rover", "dls"]
ShapeKind = Literal["box", "sphere", "cylinder", "capsule", "mesh"]


@dataclass(frozen=True)
class DHJoint:
    """One revolute joint of a DH chain (metres, radians).

    ``modified`` (Craig): ``prev_T_i = Rx(alpha) Tx(a) Rz(theta) Tz(d)`` where (a, alpha) are the
    table's a_{i-1}, alpha_{i-1}.
    ``standard`` (Denavit-Hartenberg, Angeles' a_i, b_i): ``i_T_next = Rz(theta) Tz(d) Tx(a) Rx(alpha)``.
    The DH angle is ``theta = sign * q + offset`` where q is the joint variable the operator sees.
    """

    a: float
    alpha: float
    d: float
    offset: float = 0.0
    sign: int = 1
    lower: float = -np.pi
    upper: float = np.pi
    name: str = ""


@dataclass(frozen=True)
class UrdfJoint:
    """One revolute joint of a URDF robot (radians): its name, range, the links it joins and
    its axis in the child link's frame. URDF robots have no DH parameters; their kinematics
    live in the pinocchio model built from the file."""

    name: str
    lower: float
    upper: float
    parent_link: str = ""
    child_link: str = ""
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class LinkShape:
    """A collision/display shape fixed to a link, posed by ``link_T_shape`` (4, 4).

    box: ``size`` (3,) full extents; sphere: ``radius``; cylinder: ``radius``, ``length`` along
    the shape's z, centred; capsule: ``radius``, ``length`` of the segment along z, centred;
    mesh: ``mesh_path`` (absolute) and ``scale`` (3,).
    """

    kind: ShapeKind
    link_T_shape: np.ndarray
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    length: float = 0.0
    mesh_path: str = ""
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    color: tuple[int, int, int] = (200, 200, 200)


@dataclass(frozen=True)
class RobotDescription:
    """Everything a robot file says, in SI units."""

    name: str
    source: str
    convention: DHConvention | None  # None for URDF robots
    joints: tuple[DHJoint | UrdfJoint, ...]  # UrdfJoint only when convention is None
    flange_T_tool: np.ndarray  # fixed transform after the last joint frame (4, 4)
    ik: IKKind
    # geometry per link index: 0 is the base, i is the link moved by joint i
    shapes: dict[int, tuple[LinkShape, ...]] = field(default_factory=dict)
    always_in_contact: tuple[tuple[int, int], ...] = ()
    urdf_path: str | None = None
    urdf_tool_frame: str | None = None
    link_names: tuple[str, ...] = ()
    # where the DH chain starts in the robot's base frame (4, 4): the mount of the first joint
    base_T_chain: np.ndarray = field(default_factory=lambda: np.eye(4))
    # how far past a joint limit (rad) an IK solution may fall and still be taken, clamped to the
    # limit (so it reaches its target only to within that much): a target printed to a rounding
    # (seed 004's Table 2, to 1 mm) must not lose a solution that sits on a limit
    ik_limit_tolerance: float = IK_LIMIT_TOLERANCE

    @property
    def dof(self) -> int:
        return len(self.joints)

    @property
    def lower(self) -> np.ndarray:
        return np.array([j.lower for j in self.joints])

    @property
    def upper(self) -> np.ndarray:
        return np.array([j.upper for j in self.joints])
