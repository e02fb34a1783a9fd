"""The one exception tree of the project.

    TeleprogError                 anything the project raises on purpose
    ├── InputError                bad input from a person or a file (says what and where)
    │   ├── FileFormatError       a data file (robot, cell, mesh, program) that cannot be used
    │   └── UnknownNameError      a name that is not one of the valid choices (lists them)
    ├── KinematicsError           a kinematic request that cannot be met
    │   ├── UnreachableError      no inverse-kinematics solution
    │   └── JointLimitError       a joint vector outside the robot's ranges
    └── JogBlocked                a jog step refused (limit, singularity), with the reason

The CLI turns any ``TeleprogError`` into one line on stderr and a non-zero exit.
"""

from __future__ import annotations

from collections.abc import Iterable


class TeleprogError(Exception):
    """Base of every error the project raises on purpose."""


class InputError(TeleprogError):
    """Bad input from a person or a file."""


class FileFormatError(InputError):
    """A data file that cannot be used; the message names the file and the field."""

    def __init__(self, path: object, message: str, field: str | None = None) -> None:
        self.path = str(path)
        self.field = field
        where = f"{self.path}: {field}: " if field else f"{self.path}: "
        super().__init__(where + message)


class UnknownNameError(InputError):
    """A name that is not one of the valid choices."""

    def __init__(self, what: str, name: str, choices: Iterable[str]) -> None:
        self.what = what
        self.name = name
        self.choices = sorted(choices)
        super().__init__(f"unknown {what} {name!r}; valid: {', '.join(self.choices) or '(none)'}")


class KinematicsError(TeleprogError):
    """A kinematic request that cannot be met."""


class UnreachableError(KinematicsError):
    """No inverse-kinematics solution for the target."""


class JointLimitError(KinematicsError):
    """A joint vector outside the robot's joint ranges."""


class JogBlocked(KinematicsError):
    """A jog step refused; ``reason`` is one of 'joint_limit', 'singularity', 'unreachable'."""

    def __init__(self, reason: str, message: str) -> None:
        self.reason = reason
        super().__init__(message)
