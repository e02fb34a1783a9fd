"""Typed statements -> the text form, exactly reversible by :mod:`shared.language.parser`.

Every number is written with :func:`shared.language.units.from_si`, which picks the shortest
decimal that the parser's own conversion maps back to the very same float, so
text -> JSON -> text -> JSON reproduces the JSON bit for bit. Optional parts are written in one
canonical order (``IN``, then ``WITH``, then ``UNTIL``); the default frame is left out.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence

from shared.errors import InputError

from shared.language.statements import (
    DEFAULT_FRAME,
    SPEED_TEXT_UNIT,
    Draw,
    Drive,
    Event,
    Move,
    Moves,
    Rotate,
    SetMode,
    SetSpeed,
    Speed,
    Statement,
    TaskCall,
    UntilContact,
    UntilForce,
    UntilTime,
)
from shared.language.units import ConversionError, TextUnit, from_si

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")



def _tuple(values: Sequence[float], unit: TextUnit) -> str:
    return "(" + ", ".join(from_si(float(v), unit) for v in values) + f") {unit.value}"


def format_speed(speed: Speed) -> str:
    unit = SPEED_TEXT_UNIT[speed.unit]
    return f"{from_si(speed.value, unit)} {unit.value}"


def _tail(statement: Draw | Drive | Move | Moves | Rotate) -> str:
    parts = []
    frame = getattr(statement, "frame", DEFAULT_FRAME)
    if frame != DEFAULT_FRAME:
        parts.append(f"IN {frame.value}")
    if statement.speed is not None:
        parts.append(f"WITH SPEED {format_speed(statement.speed)}")
    until = statement.until
    if isinstance(until, UntilForce):
        parts.append(f"UNTIL FORCE > {from_si(until.newtons, TextUnit.NEWTON)} N")
    elif isinstance(until, UntilContact):
        parts.append("UNTIL CONTACT")
    elif isinstance(until, UntilTime):
        parts.append(f"UNTIL TIME {from_si(until.seconds, TextUnit.SECOND)} s")
    return "".join(" " + p for p in parts)


def format_statement(statement: Statement) -> str:
    """One statement as one line of text (no newline). Raises ``InputError`` for values the
    text cannot hold (NaN, infinity, a task argument that is not a name)."""
    try:
        return _format(statement)
    except ConversionError as exc:
        raise InputError(f"{statement.kind}: {exc}") from None


def _format(statement: Statement) -> str:
    if isinstance(statement, Move):
        return "MOVE " + _tuple(statement.joints, TextUnit.DEG) + _tail(statement)
    if isinstance(statement, Drive):
        return f"DRIVE J{statement.joint} TO {from_si(statement.target, TextUnit.DEG)} deg" + _tail(statement)
    if isinstance(statement, Draw):
        return "DRAW TO " + _tuple(statement.position, TextUnit.MM) + _tail(statement)
    if isinstance(statement, Rotate):
        return "ROTATE TO " + _tuple(statement.rpy, TextUnit.DEG) + _tail(statement)
    if isinstance(statement, Moves):
        return (
            "MOVES TO " + _tuple(statement.position, TextUnit.MM) + " " + _tuple(statement.rpy, TextUnit.DEG)
            + _tail(statement)
        )
    if isinstance(statement, SetSpeed):
        return f"SPEED {format_speed(statement.speed)}"
    if isinstance(statement, SetMode):
        return f"MODE {statement.mode.value}"
    if isinstance(statement, Event):
        return f"EVENT {statement.name}"
    if isinstance(statement, TaskCall):
        for arg in statement.args:
            if not _IDENT.fullmatch(arg):
                raise InputError(f"TASK {statement.name}: argument {arg!r} is not a name (letters, digits, _)")
        return f"TASK {statement.name}({', '.join(statement.args)})"
    raise TypeError(f"not a statement: {statement!r}")


def format_program(statements: Iterable[Statement]) -> str:
    """The text form of a program: one statement a line, ending with a newline."""
    return "".join(format_statement(s) + "\n" for s in statements)
