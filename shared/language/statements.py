"""The statements of the teleprogramming language: one typed definition each.

These models are the JSON form of a program (a list of statements, each an object with a
``"kind"``), the body of command units on the wire, and what the interpreter executes. Values are
SI: lengths in metres, angles in radians, speeds in m/s, rad/s or a fraction of the robot's
maximum, forces in newtons, times in seconds. The text form (``shared.language.parser`` and
``shared.language.formatter``) is where millimetres, degrees and percent appear.

Kinds:

========  ======================================  ==========================================
kind      text form                               what it does
========  ======================================  ==========================================
MOVE      ``MOVE (q1, ..., qn) deg``              joint-interpolated move to a full joint vector
DRIVE     ``DRIVE J3 TO -30 deg``                 one joint to an angle
DRAW      ``DRAW TO (x, y, z) mm IN WORK``        straight line, position only
ROTATE    ``ROTATE TO (r, p, y) deg IN WORK``     orientation only (fixed-axis XYZ roll-pitch-yaw)
MOVES     ``MOVES TO (x,y,z) mm (r,p,y) deg``     straight line, position and orientation
SPEED     ``SPEED 50 %``                          speed of the following actions
MODE      ``MODE FORCE`` / ``MODE POSITION``      control mode of the following actions
EVENT     ``EVENT name``                          a named mark the robot reports when reached
TASK      ``TASK insert_peg(PEG, HOLE1)``         a task the robot already knows
========  ======================================  ==========================================

MOVE, DRIVE, DRAW, ROTATE and MOVES are *actions* and may carry ``WITH SPEED ...`` and
``UNTIL ...``; SPEED, MODE and EVENT are *parameter* statements; TASK is a *task call*.
"""

from __future__ import annotations

from enum import Enum
from typing import Annotated, Literal, Union

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, TypeAdapter, model_validator
from pydantic_core import PydanticCustomError

from shared.language import bounds
from shared.language.bounds import describe
from shared.language.units import TextUnit


def _within(limit: float, unit: str, what: str):
    """A validator refusing ``|v| > limit``; the message gives the value, the unit and the bound."""

    def check(v: float) -> float:
        if not -limit <= v <= limit:
            raise PydanticCustomError(
                "out_of_bounds", "{value} {unit} is beyond the {what} of \u00b1{limit} {unit}",
                {"value": describe(v), "unit": unit, "what": what, "limit": describe(limit)},
            )
        return v

    return AfterValidator(check)


def _at_most(limit: float, unit: str, what: str):
    def check(v: float) -> float:
        if v > limit:
            raise PydanticCustomError(
                "out_of_bounds", "{value} {unit} is above the {what} of {limit} {unit}",
                {"value": describe(v), "unit": unit, "what": what, "limit": describe(limit)},
            )
        return v

    return AfterValidator(check)


Metres = Annotated[float, _within(bounds.WORKSPACE_M, "m", "workspace bound")]
"""A coordinate of a Cartesian target (finite, within the workspace bound)."""
Radians = Annotated[float, _within(bounds.MAX_ANGLE_RAD, "rad", "angle bound")]
"""A joint angle or roll/pitch/yaw (finite, at most two turns either way)."""
Vec3 = tuple[Metres, Metres, Metres]
Rpy = tuple[Radians, Radians, Radians]
Name = Annotated[str, Field(min_length=1, max_length=bounds.MAX_NAME_LENGTH, pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")]
"""An EVENT or TASK name, or a task argument: an identifier of at most ``MAX_NAME_LENGTH``."""


class Frame(str, Enum):
    """Frames a Cartesian target may be given in (see ``shared/CONVENTIONS.md``)."""

    WORLD = "WORLD"
    BASE = "BASE"
    WORK = "WORK"
    TOOL = "TOOL"


DEFAULT_FRAME = Frame.WORLD
"""Frame of a Cartesian target written without ``IN``."""


class SpeedUnit(str, Enum):
    """Units of a speed value: a fraction of the robot's maximum, or an absolute rate."""

    FRACTION = "fraction"  # text: percent; 0.2 here is "20 %"
    M_PER_S = "m/s"  # text: mm/s
    RAD_PER_S = "rad/s"  # text: deg/s


SPEED_TEXT_UNIT: dict[SpeedUnit, TextUnit] = {
    SpeedUnit.FRACTION: TextUnit.PERCENT, SpeedUnit.M_PER_S: TextUnit.MM_PER_S, SpeedUnit.RAD_PER_S: TextUnit.DEG_PER_S,
}
"""The text unit each speed unit is written in (the parser reads it the other way)."""
SPEED_UNIT_TEXT: dict[SpeedUnit, str] = {k: v.value for k, v in SPEED_TEXT_UNIT.items()}
"""How each speed unit is spelled in the text form."""

ALLOWED_SPEED_UNITS: dict[str, tuple[SpeedUnit, ...]] = {
    "MOVE": (SpeedUnit.FRACTION, SpeedUnit.RAD_PER_S),
    "DRIVE": (SpeedUnit.FRACTION, SpeedUnit.RAD_PER_S),
    "DRAW": (SpeedUnit.FRACTION, SpeedUnit.M_PER_S),
    "ROTATE": (SpeedUnit.FRACTION, SpeedUnit.RAD_PER_S),
    "MOVES": (SpeedUnit.FRACTION, SpeedUnit.M_PER_S, SpeedUnit.RAD_PER_S),
}
"""Speed units each action takes: a joint move a fraction or deg/s, a line mm/s, a rotation
deg/s, a full pose any (one table for the checks and the planner)."""


class Mode(str, Enum):
    POSITION = "POSITION"
    FORCE = "FORCE"


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


SPEED_BOUND: dict[SpeedUnit, float] = {
    SpeedUnit.FRACTION: bounds.MAX_SPEED_FRACTION,
    SpeedUnit.M_PER_S: bounds.MAX_LINEAR_SPEED_M_S,
    SpeedUnit.RAD_PER_S: bounds.MAX_ANGULAR_SPEED_RAD_S,
}
"""The physical bound of a speed in each unit (the robot's own maximum is the checks' business)."""
SPEED_MIN: dict[SpeedUnit, float] = {
    SpeedUnit.FRACTION: bounds.MIN_SPEED_FRACTION,
    SpeedUnit.M_PER_S: bounds.MIN_LINEAR_SPEED_M_S,
    SpeedUnit.RAD_PER_S: bounds.MIN_ANGULAR_SPEED_RAD_S,
}
"""The slowest speed in each unit: below it a motion could not finish in a working day
(``bounds.MAX_MOTION_S``), and a speed of 5e-324 would divide by zero in a planner."""


class Speed(_Model):
    """A speed: ``value`` in ``unit``; a fraction of the robot's maximum is in (0, 1] for the
    checks and the planner (the model itself refuses only what no robot can mean: above
    ``SPEED_BOUND``, or below ``SPEED_MIN``, too slow to finish in a working day)."""

    value: float = Field(gt=0.0)
    unit: SpeedUnit

    @model_validator(mode="after")
    def _bounded(self) -> "Speed":
        limit = SPEED_BOUND[self.unit]
        if self.value > limit:
            raise PydanticCustomError(
                "out_of_bounds", "value {value} {unit} is above the speed bound of {limit} {unit}",
                {"value": describe(self.value), "unit": self.unit.value, "limit": describe(limit)},
            )
        slowest = SPEED_MIN[self.unit]
        if self.value < slowest * (1.0 - 1e-9):  # the bound itself, however its unit converted, passes
            raise PydanticCustomError(
                "out_of_bounds",
                "value {value} {unit} is below the slowest speed bound of {limit} {unit} "
                "(a motion at it could not finish within {hours} h)",
                {"value": describe(self.value), "unit": self.unit.value, "limit": describe(slowest),
                 "hours": describe(bounds.MAX_MOTION_S / 3600.0)},
            )
        return self


class UntilForce(_Model):
    """Stop when the magnitude of the measured force exceeds ``newtons``."""

    kind: Literal["force"] = "force"
    newtons: Annotated[float, Field(gt=0.0), _at_most(bounds.MAX_FORCE_N, "N", "force bound")]


class UntilContact(_Model):
    """Stop at the first contact the robot senses."""

    kind: Literal["contact"] = "contact"


class UntilTime(_Model):
    """Stop after ``seconds`` of motion."""

    kind: Literal["time"] = "time"
    seconds: Annotated[float, Field(gt=0.0), _at_most(bounds.MAX_TIME_S, "s", "time bound")]


Until = Annotated[Union[UntilForce, UntilContact, UntilTime], Field(discriminator="kind")]


class _Action(_Model):
    """Fields every action has: an optional speed and an optional stop condition."""

    speed: Speed | None = None
    until: Until | None = None


class Move(_Action):
    """Joint-interpolated move to a full joint vector (radians)."""

    kind: Literal["MOVE"] = "MOVE"
    joints: tuple[Radians, ...] = Field(min_length=1, max_length=bounds.MAX_JOINTS)


class Drive(_Action):
    """Move one joint (1-based number) to ``target`` (radians)."""

    kind: Literal["DRIVE"] = "DRIVE"
    joint: int = Field(ge=1, le=bounds.MAX_JOINTS)
    target: Radians


class Draw(_Action):
    """Straight-line move of the tool point to ``position`` (metres in ``frame``); orientation kept."""

    kind: Literal["DRAW"] = "DRAW"
    position: Vec3
    frame: Frame = DEFAULT_FRAME


class Rotate(_Action):
    """Rotate the tool in place to ``rpy`` (fixed-axis XYZ roll, pitch, yaw; radians in ``frame``)."""

    kind: Literal["ROTATE"] = "ROTATE"
    rpy: Rpy
    frame: Frame = DEFAULT_FRAME


class Moves(_Action):
    """Straight-line move to a full tool pose: ``position`` (m) and ``rpy`` (rad) in ``frame``."""

    kind: Literal["MOVES"] = "MOVES"
    position: Vec3
    rpy: Rpy
    frame: Frame = DEFAULT_FRAME


class SetSpeed(_Model):
    """Speed of the actions that follow (until the next SPEED)."""

    kind: Literal["SPEED"] = "SPEED"
    speed: Speed


class SetMode(_Model):
    """Control mode of the actions that follow."""

    kind: Literal["MODE"] = "MODE"
    mode: Mode


class Event(_Model):
    """A named mark; the robot reports it when execution reaches it."""

    kind: Literal["EVENT"] = "EVENT"
    name: Name


class TaskCall(_Model):
    """A task the robot knows, by name, with object or feature names as arguments."""

    kind: Literal["TASK"] = "TASK"
    name: Name
    args: tuple[Name, ...] = Field(default=(), max_length=bounds.MAX_TASK_ARGS)


Action = Union[Move, Drive, Draw, Rotate, Moves]
Parameter = Union[SetSpeed, SetMode, Event]
Statement = Annotated[
    Union[Move, Drive, Draw, Rotate, Moves, SetSpeed, SetMode, Event, TaskCall], Field(discriminator="kind")
]

ACTION_KINDS = frozenset({"MOVE", "DRIVE", "DRAW", "ROTATE", "MOVES"})
PARAMETER_KINDS = frozenset({"SPEED", "MODE", "EVENT"})
TASK_KINDS = frozenset({"TASK"})

statement_adapter: TypeAdapter[Statement] = TypeAdapter(Statement)
program_adapter: TypeAdapter[list[Statement]] = TypeAdapter(
    Annotated[list[Statement], Field(max_length=bounds.MAX_PROGRAM_STATEMENTS)]
)


def is_action(statement: object) -> bool:
    return getattr(statement, "kind", None) in ACTION_KINDS


def is_parameter(statement: object) -> bool:
    return getattr(statement, "kind", None) in PARAMETER_KINDS


def is_task(statement: object) -> bool:
    return getattr(statement, "kind", None) in TASK_KINDS


def program_to_json(statements: list[Statement]) -> list[dict]:
    """The JSON form of a program: one object per statement, SI values, no ``None`` fields."""
    return [s.model_dump(mode="json", exclude_none=True) for s in statements]


def program_from_json(data: object) -> list[Statement]:
    """Validate the JSON form (already decoded); raises ``pydantic.ValidationError``."""
    return program_adapter.validate_python(data)
