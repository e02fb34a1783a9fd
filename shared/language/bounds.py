"""Physical bounds of the statement language: what no statement of any robot may exceed.

These bounds catch garbage (a NaN, 1e308 m, a 10 MB event name) at every boundary where a
statement enters as data: the text form, the JSON form, a wire unit, the HTTP API. They are
deliberately generous: whether a value suits *this* robot (its joint ranges, its reach, 100 % of
its speed) is :mod:`shared.language.checks` and the planner. Values are SI, as in the models.
"""

from __future__ import annotations

import math

WORKSPACE_M = 100.0
"""Largest coordinate of a Cartesian target (m), in any frame: no cell here is wider than a few
metres (the rover terrain spans 1.1 m), so 100 m only refuses what cannot be a position."""

MAX_ANGLE_RAD = 4.0 * math.pi
"""Largest joint angle or roll/pitch/yaw (rad), 720 deg: two turns either way (a URDF continuous
joint ranges over 2 pi each way)."""

MAX_SPEED_FRACTION = 10.0
"""Largest fraction of the robot's maximum speed a statement may hold (1000 %). Above 100 % is
refused by the checks and the planner, with the robot named; this bound refuses nonsense."""

MAX_LINEAR_SPEED_M_S = 10.0
"""Largest tool-point speed (m/s)."""

MAX_ANGULAR_SPEED_RAD_S = 20.0
"""Largest joint or rotation speed (rad/s), about 1146 deg/s."""

MAX_MOTION_S = 8 * 3600.0
"""Longest one motion may take (s): a working day. The slowest speeds below keep every motion a
robot of this project can make well within it; the planner refuses any motion planned longer
(``shared.motion.interpreter``), so no statement keeps a robot busy for days."""

MIN_SPEED_FRACTION = 1e-3
"""Slowest fraction of the robot's maximum speed a statement may hold (0.1 %)."""

MIN_LINEAR_SPEED_M_S = 1e-4
"""Slowest tool-point speed (m/s), 0.1 mm/s: 2.88 m in ``MAX_MOTION_S``, longer than any line a
robot here can draw (the PUMA's reach is under 1 m, the rover's terrain 1.1 m wide)."""

MIN_ANGULAR_SPEED_RAD_S = math.radians(0.1)
"""Slowest joint or rotation speed (rad/s), 0.1 deg/s: the longest joint travel the angle bound
allows (1440 deg, from -720 to 720 deg) takes 4 h, half of ``MAX_MOTION_S``."""

MAX_FORCE_N = 10_000.0
"""Largest force threshold of ``UNTIL FORCE`` (N)."""

MAX_TIME_S = 3600.0
"""Longest ``UNTIL TIME`` (s): one hour (within ``MAX_MOTION_S``)."""

MAX_JOINTS = 32
"""Most joint values in a MOVE and the highest joint number of a DRIVE."""

MAX_NAME_LENGTH = 64
"""Longest EVENT name, TASK name or task argument (characters)."""

MAX_TASK_ARGS = 8
"""Most arguments of one task call."""

MAX_PROGRAM_STATEMENTS = 200_000
"""Most statements in one program (text or JSON form)."""

MAX_PROGRAM_BYTES = 8 * 1024 * 1024
"""Largest program file or text read (8 MiB); reading stops there, so an endless stream ends."""


def describe(value: float) -> str:
    """A short spelling of a number for a message (``1e+308``, ``0.25``)."""
    return f"{value:.6g}"
