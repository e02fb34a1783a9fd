"""Telemetry frames of the data channel: one fixed-size binary layout (thesis §4.4, data channel).

The robot sends one frame every 20 ms (50 Hz), each a binary WebSocket message of exactly
``FRAME_SIZE`` bytes. Fixed size is what lets the receiver check a frame by its length alone and
decode a whole recording at once (``decode_frames`` views a byte string as an array, no loop).

Layout: the numpy structured dtype ``FRAME_DTYPE``, packed, little-endian, 174 bytes::

    offset  field      type       unit / meaning
    0       magic      2 bytes    b"TF"
    2       version    u1         1
    3       state      u1         RobotState code (idle, running, stopped, fault, disconnected)
    4       mode       u1         ControlMode code (position, force)
    5       dof        u1         how many entries of q are used (1..6)
    6       time       f8         robot clock, s
    14      frame      u4         frame number, +1 per frame from 0
    18      statement  u4         number of the statement being executed, 0 when none
    22      q          6 x f8     joint angles, rad; entries past dof are 0
    70      position   3 x f8     tool point in the base frame, m
    94      rpy        3 x f8     tool orientation, fixed-axis XYZ roll-pitch-yaw, rad
    118     gripper    f8         gripper opening, m
    126     wrench     6 x f8     force (N) then torque (N m) at the tool, in the tool frame
    174     (end)
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from shared.errors import InputError
from shared.wire.messages import ControlMode, RobotState

FRAME_MAGIC = b"TF"
FRAME_VERSION = 1
FRAME_RATE_HZ = 50.0
MAX_JOINTS = 6

FRAME_DTYPE = np.dtype(
    [
        ("magic", "S2"),
        ("version", "u1"),
        ("state", "u1"),
        ("mode", "u1"),
        ("dof", "u1"),
        ("time", "<f8"),
        ("frame", "<u4"),
        ("statement", "<u4"),
        ("q", "<f8", (MAX_JOINTS,)),
        ("position", "<f8", (3,)),
        ("rpy", "<f8", (3,)),
        ("gripper", "<f8"),
        ("wrench", "<f8", (6,)),
    ],
    align=False,
)
FRAME_SIZE = FRAME_DTYPE.itemsize
assert FRAME_SIZE == 174, FRAME_SIZE  # the documented layout; a change here is a protocol change

_FRAME_STRUCT = struct.Struct("<2sBBBBdII6d3d3dd6d")
"""``FRAME_DTYPE`` as a ``struct`` format, for one frame at a time (``decode_frame``): one C call
gives every field as a Python number, where numpy's structured scalars cost a few microseconds
per field read and more on a cold core, 50 times a second."""
assert _FRAME_STRUCT.size == FRAME_SIZE
_STATES = {int(s): s for s in RobotState}
_MODES = {int(m): m for m in ControlMode}
_MAX_STATE, _MAX_MODE = int(max(RobotState)), int(max(ControlMode))


class TelemetryError(InputError):
    """A byte string that is not a valid telemetry frame."""


@dataclass(frozen=True)
class TelemetryFrame:
    """One decoded frame; ``q`` holds only the ``dof`` joints in use."""

    time: float
    frame: int
    state: RobotState
    mode: ControlMode
    statement: int
    q: tuple[float, ...]
    position: tuple[float, float, float]
    rpy: tuple[float, float, float]
    gripper: float = 0.0
    wrench: tuple[float, ...] = field(default=(0.0,) * 6)


def encode_frame(f: TelemetryFrame) -> bytes:
    """The ``FRAME_SIZE`` bytes of one frame."""
    dof = len(f.q)
    if not 1 <= dof <= MAX_JOINTS:
        raise TelemetryError(f"telemetry frame: {dof} joints; 1 to {MAX_JOINTS} fit in a frame")
    if len(f.wrench) != 6:
        raise TelemetryError(f"telemetry frame: wrench has {len(f.wrench)} entries; expected 6")
    rec = np.zeros((), dtype=FRAME_DTYPE)
    rec["magic"] = FRAME_MAGIC
    rec["version"] = FRAME_VERSION
    rec["state"] = int(f.state)
    rec["mode"] = int(f.mode)
    rec["dof"] = dof
    rec["time"] = f.time
    rec["frame"] = f.frame & 0xFFFFFFFF
    rec["statement"] = f.statement
    rec["q"][:dof] = f.q
    rec["position"] = f.position
    rec["rpy"] = f.rpy
    rec["gripper"] = f.gripper
    rec["wrench"] = f.wrench
    return rec.tobytes()


def decode_frames(data: bytes) -> np.ndarray:
    """A recording of whole frames as a structured array (no copy); checks sizes and headers."""
    if len(data) % FRAME_SIZE:
        raise TelemetryError(f"telemetry: {len(data)} bytes is not a whole number of {FRAME_SIZE}-byte frames")
    frames = np.frombuffer(data, dtype=FRAME_DTYPE)
    bad = (frames["magic"] != FRAME_MAGIC) | (frames["version"] != FRAME_VERSION)
    bad |= (frames["dof"] < 1) | (frames["dof"] > MAX_JOINTS) | (frames["state"] > max(RobotState))
    bad |= frames["mode"] > max(ControlMode)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise TelemetryError(f"telemetry: frame {i} has a bad header (magic, version, dof, state or mode)")
    return frames


def decode_frame(data: bytes) -> TelemetryFrame:
    """One frame from exactly ``FRAME_SIZE`` bytes: the same checks and values as
    ``decode_frames(data)[0]`` (``struct`` reads the same little-endian layout)."""
    if len(data) != FRAME_SIZE:
        raise TelemetryError(f"telemetry frame of {len(data)} bytes; expected {FRAME_SIZE}")
    v = _FRAME_STRUCT.unpack(data)
    magic, version, state, mode, dof = v[0], v[1], v[2], v[3], v[4]
    if (magic != FRAME_MAGIC or version != FRAME_VERSION or not 1 <= dof <= MAX_JOINTS or state > _MAX_STATE
            or mode > _MAX_MODE):
        raise TelemetryError("telemetry: frame 0 has a bad header (magic, version, dof, state or mode)")
    robot_state, control_mode = _STATES.get(state), _MODES.get(mode)
    return TelemetryFrame(
        time=v[5],
        frame=v[6],
        state=robot_state if robot_state is not None else RobotState(state),
        mode=control_mode if control_mode is not None else ControlMode(mode),
        statement=v[7],
        q=v[8:8 + dof],
        position=v[14:17],
        rpy=v[17:20],
        gripper=v[20],
        wrench=v[21:27],
    )
