"""The robot interface: one immutable pinocchio model per robot, per-caller data.

``Robot`` is built once from a ``RobotDescription`` (see ``shared.robots.loader``). Every user
(GUI, planner, simulator, collision) calls the methods with its own ``pin.Data`` from
``robot.new_data()``, or lets the robot use a per-thread default.

Frames: ``base`` is frame 0 of the robot's DH table (or the URDF root); ``tool`` is the robot's
tool point (PUMA: DH frame 6, the flange; rover: point C; URDF: the tool link's frame, see
``shared.robots.urdf``); link ``i`` is the body moved by joint ``i`` (link 0 is the base).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from shared.errors import InputError, JointLimitError
from shared.robots.description import LinkShape, RobotDescription
from shared.spatial import rot_x, rot_z

#: tolerance (rad) when deciding whether a joint value is inside its range
LIMIT_TOLERANCE = 1e-9


def _joint_model(sign: int) -> pin.JointModel:
    if sign == 1:
        return pin.JointModelRZ()
    return pin.JointModelRevoluteUnaligned(np.array([0.0, 0.0, -1.0]))


def _se3(transform: np.ndarray) -> pin.SE3:
    return pin.SE3(np.ascontiguousarray(transform[:3, :3]), np.ascontiguousarray(transform[:3, 3]))


def _homogeneous(rotation: np.ndarray, translation: Sequence[float]) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = translation
    return out


def build_dh_model(desc: RobotDescription) -> tuple[pin.Model, int, tuple[int, ...]]:
    """Build a pinocchio model of a DH chain.

    Returns the model, the id of the ``tool`` frame and the frame id of every link (index 0 is
    the base, ``universe``).
    """
    model = pin.Model()
    model.name = desc.name
    parent = 0
    previous_fixed = np.eye(4)  # standard DH: the fixed part after the previous joint
    for i, joint in enumerate(desc.joints, start=1):
        if desc.convention == "modified":
            placement = _homogeneous(
                rot_x(joint.alpha) @ rot_z(joint.offset),
                [joint.a, -joint.d * np.sin(joint.alpha), joint.d * np.cos(joint.alpha)],
            )
        else:
            placement = previous_fixed @ _homogeneous(rot_z(joint.offset), [0.0, 0.0, 0.0])
            previous_fixed = (
                _homogeneous(np.eye(3), [0.0, 0.0, joint.d])
                @ _homogeneous(np.eye(3), [joint.a, 0.0, 0.0])
                @ _homogeneous(rot_x(joint.alpha), [0.0, 0.0, 0.0])
            )
        if i == 1:
            placement = desc.base_T_chain @ placement
        name = joint.name or f"joint{i}"
        joint_id = model.addJoint(
            parent,
            _joint_model(joint.sign),
            _se3(placement),
            name,
            np.array([1e3]),
            np.array([1e3]),
            np.array([joint.lower]),
            np.array([joint.upper]),
        )
        model.appendBodyToJoint(joint_id, pin.Inertia.Random(), pin.SE3.Identity())
        model.addFrame(pin.Frame(f"link{i}", joint_id, pin.SE3.Identity(), pin.FrameType.BODY))
        parent = joint_id
    flange = previous_fixed if desc.convention == "standard" else np.eye(4)
    tool_placement = flange @ desc.flange_T_tool
    tool_id = model.addFrame(
        pin.Frame("tool", parent, _se3(tool_placement), pin.FrameType.OP_FRAME)
    )
    link_ids = (0,) + tuple(model.getFrameId(f"link{i}") for i in range(1, len(desc.joints) + 1))
    return model, tool_id, link_ids


class Robot:
    """A loaded robot: immutable model, joint ranges, geometry, and kinematics methods.

    Arrays: ``q`` is ``(dof,)`` in radians; poses are ``(4, 4)`` in metres in the base frame.
    """

    def __init__(
        self,
        description: RobotDescription,
        model: pin.Model,
        tool_frame_id: int,
        link_frame_ids: tuple[int, ...],
    ) -> None:
        self.description = description
        self.name = description.name
        self.model = model
        self.tool_frame_id = tool_frame_id
        self.link_frame_ids = link_frame_ids
        self.dof = int(model.nq)
        self.lower = np.array(model.lowerPositionLimit, dtype=float)
        self.upper = np.array(model.upperPositionLimit, dtype=float)
        self.joint_names = tuple(model.names[1:])
        self._local = threading.local()

    # -- data -------------------------------------------------------------------------------
    def new_data(self) -> pin.Data:
        return self.model.createData()

    def _data(self, data: pin.Data | None) -> pin.Data:
        if data is not None:
            return data
        cached = getattr(self._local, "data", None)
        if cached is None:
            cached = self._local.data = self.model.createData()
        return cached

    @property
    def shapes(self) -> dict[int, tuple[LinkShape, ...]]:
        return self.description.shapes

    # -- checks -----------------------------------------------------------------------------
    def as_q(self, q: Sequence[float] | np.ndarray) -> np.ndarray:
        """Validate the length and finiteness of a joint vector; return it as ``(dof,)`` floats."""
        arr = np.asarray(q, dtype=float).reshape(-1)
        if arr.shape != (self.dof,):
            raise InputError(f"robot {self.name!r} has {self.dof} joints, got {arr.size} values")
        if not np.all(np.isfinite(arr)):
            raise InputError(f"joint vector for {self.name!r} contains NaN or infinity")
        return arr

    def within_limits(self, q: np.ndarray, tol: float = LIMIT_TOLERANCE) -> bool:
        return bool(np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol))

    def check_limits(self, q: np.ndarray) -> None:
        """Raise ``JointLimitError`` naming the first joint outside its range (degrees)."""
        for i in range(self.dof):
            if not (self.lower[i] - LIMIT_TOLERANCE <= q[i] <= self.upper[i] + LIMIT_TOLERANCE):
                raise JointLimitError(
                    f"joint {i + 1} of {self.name!r} at {np.degrees(q[i]):.3f} deg is outside its range "
                    f"[{np.degrees(self.lower[i]):.3f}, {np.degrees(self.upper[i]):.3f}] deg"
                )

    # -- kinematics -------------------------------------------------------------------------
    def fk(self, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """``base_T_tool`` (4, 4) at joint vector ``q``."""
        d = self._data(data)
        pin.framesForwardKinematics(self.model, d, q)
        return d.oMf[self.tool_frame_id].homogeneous

    def link_poses(self, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """``base_T_link`` for every link, ``(dof + 1, 4, 4)``; index 0 is the base."""
        d = self._data(data)
        pin.framesForwardKinematics(self.model, d, q)
        return np.stack([d.oMf[fid].homogeneous for fid in self.link_frame_ids])

    def jacobian(self, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """Tool Jacobian ``(6, dof)``: rows (v, omega) of the tool point, base-aligned axes."""
        d = self._data(data)
        return pin.computeFrameJacobian(self.model, d, q, self.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, dof={self.dof})"
