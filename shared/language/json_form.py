"""The JSON form of statements read strictly, with every error located by a JSON pointer.

Outside JSON (a ``.json`` program, a command unit's body) is decoded with
``shared.wire.strict_json.loads_strict``: no NaN or Infinity, no number that overflows, no key
given twice. When it refuses a document, :func:`locate_fault` reads it once more, leniently,
only to say *where*: the RFC 6901 pointer of the offending value (``/3/target``). Model errors
of pydantic are turned into the same pointers (:func:`pointer_from_loc`), so every message
names the place in the document, never "statement N".
"""

from __future__ import annotations

import json
import math
from typing import Any

from pydantic import ValidationError

from shared.language.statements import Statement, program_adapter, statement_adapter
from shared.wire.strict_json import StrictJSONError, loads_strict

STATEMENT_TAGS = frozenset({"MOVE", "DRIVE", "DRAW", "ROTATE", "MOVES", "SPEED", "MODE", "EVENT", "TASK"})
UNTIL_TAGS = frozenset({"force", "contact", "time"})
_MAX_INT_DIGITS = 4300  # what Python's int() accepts from text by default


class JSONFormFault(ValueError):
    """A document that is not strict JSON: ``message`` says what, ``pointer`` where (``""`` when
    the fault is the document as a whole, e.g. a syntax error; ``message`` then has line and
    column)."""

    def __init__(self, message: str, pointer: str = "") -> None:
        super().__init__(f"{pointer}: {message}" if pointer else message)
        self.message = message
        self.pointer = pointer


def pointer(parts: tuple[str | int, ...] | list[str | int]) -> str:
    """RFC 6901 pointer of a path: ``(3, "target")`` -> ``/3/target``."""
    return "".join("/" + str(p).replace("~", "~0").replace("/", "~1") for p in parts)


def pointer_from_loc(loc: tuple[Any, ...], prefix: tuple[str | int, ...] = ()) -> str:
    """The document path of a pydantic error location: the tags pydantic adds for the
    discriminated unions (``DRIVE``, ``force``) are dropped, they are not keys of the document."""
    parts: list[str | int] = list(prefix)
    previous: object = None
    for i, p in enumerate(loc):
        if isinstance(p, str) and p in STATEMENT_TAGS and (i == 0 or isinstance(previous, int)):
            previous = p
            continue
        if previous == "until" and p in UNTIL_TAGS:
            previous = p
            continue
        parts.append(p)
        previous = p
    return pointer(parts)


def validation_faults(exc: ValidationError, prefix: tuple[str | int, ...] = ()) -> list[JSONFormFault]:
    """Every error of a pydantic validation as a located fault."""
    out = []
    for err in exc.errors():
        loc = tuple(err.get("loc", ()))
        path = pointer_from_loc(loc, prefix)
        if err.get("type") in ("union_tag_invalid", "union_tag_not_found"):
            path += "/kind"
        out.append(JSONFormFault(str(err.get("msg", "invalid")), path))
    return out


class _Bad:
    """Stands in, during the locating pass, for a value strict JSON refuses."""

    __slots__ = ("why",)

    def __init__(self, why: str) -> None:
        self.why = why


def _lenient(text: str) -> Any:
    def constant(name: str) -> _Bad:
        return _Bad(f"{name} is not a JSON number (only finite numbers are accepted)")

    def number(token: str) -> Any:
        value = float(token)
        return value if math.isfinite(value) else _Bad(f"number {token[:40]} is too large to be finite")

    def integer(token: str) -> Any:
        return int(token) if len(token.lstrip("-")) <= _MAX_INT_DIGITS else _Bad(f"integer of {len(token)} digits is too long")

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, value in items:
            out[key] = _Bad(f"key {key!r} appears twice in one object") if key in out else value
        return out

    return json.loads(text, parse_constant=constant, parse_float=number, parse_int=integer, object_pairs_hook=pairs)


def _first_bad(value: Any, path: list[str | int]) -> tuple[list[str | int], str] | None:
    stack: list[tuple[Any, list[str | int]]] = [(value, path)]
    while stack:  # depth first, in document order
        node, where = stack.pop()
        if isinstance(node, _Bad):
            return where, node.why
        if isinstance(node, dict):
            stack.extend((v, where + [k]) for k, v in reversed(list(node.items())))
        elif isinstance(node, list):
            stack.extend((v, where + [i]) for i, v in reversed(list(enumerate(node))))
    return None


def locate_fault(text: str) -> tuple[str, str] | None:
    """``(pointer, message)`` of the first value strict JSON refuses in ``text``, or None when
    the fault is not one value (a syntax error, bad nesting)."""
    try:
        found = _first_bad(_lenient(text), [])
    except (ValueError, RecursionError):
        return None
    return None if found is None else (pointer(found[0]), found[1])


def loads_located(data: str | bytes | bytearray) -> Any:
    """``loads_strict`` whose refusal is a :class:`JSONFormFault` with the pointer of the fault."""
    try:
        return loads_strict(data)
    except StrictJSONError as exc:
        located = None
        if isinstance(data, str) or _is_utf8(data):
            text = data if isinstance(data, str) else bytes(data).decode("utf-8")
            located = locate_fault(text)
        if located is not None:
            raise JSONFormFault(located[1], located[0]) from None
        raise JSONFormFault(str(exc)) from None


def _is_utf8(data: bytes | bytearray) -> bool:
    try:
        bytes(data).decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


def statement_from_json(item: object, prefix: tuple[str | int, ...] = ()) -> Statement:
    """One statement from its decoded JSON form; raises the first :class:`JSONFormFault`."""
    try:
        return statement_adapter.validate_python(item)
    except ValidationError as exc:
        raise validation_faults(exc, prefix)[0] from None


def program_from_json_text(text: str | bytes) -> list[Statement]:
    """A whole program from JSON text, strictly; raises the first :class:`JSONFormFault`."""
    data = loads_located(text)
    try:
        return program_adapter.validate_python(data)
    except ValidationError as exc:
        raise validation_faults(exc)[0] from None
