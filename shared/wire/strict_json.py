"""JSON as the wire takes it: finite numbers only, one value per key, bounded nesting.

Python's ``json.loads`` accepts ``NaN``, ``Infinity`` and ``-Infinity`` (none of them JSON) and
resolves a repeated key by keeping the last value, so ``{"type": "hello", "type": "stop"}`` would
read as a stop. Every decoder of outside input (wire messages, unit bodies, program files in the
JSON form, the console's API bodies) goes through ``loads_strict`` instead, which refuses all
three with a message that says what and where.
"""

from __future__ import annotations

import json
import math
from typing import Any

MAX_DEPTH = 64
"""Deepest nesting of arrays and objects accepted (statements nest three or four levels)."""


class StrictJSONError(ValueError):
    """The text is not strict JSON; the message names the offending token or key."""


def _refuse_constant(name: str) -> Any:
    raise StrictJSONError(f"{name} is not a JSON number (only finite numbers are accepted)")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise StrictJSONError(f"key {key!r} appears twice in one object")
        out[key] = value
    return out


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):  # 1e999 parses to inf
        raise StrictJSONError(f"number {text[:40]} is too large to be finite")
    return value


def _depth(text: str) -> int:
    """Deepest bracket nesting outside strings (cheap pre-check against recursion bombs)."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > deepest:
                deepest = depth
                if deepest > MAX_DEPTH:
                    return deepest
        elif ch in "]}":
            depth -= 1
    return deepest


def loads_strict(data: str | bytes | bytearray) -> Any:
    """Parse JSON text, refusing NaN/Infinity, numbers that overflow, duplicate keys, nesting
    deeper than ``MAX_DEPTH`` and bytes that are not UTF-8. Raises ``StrictJSONError``."""
    if isinstance(data, (bytes, bytearray)):
        try:
            data = bytes(data).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise StrictJSONError(f"not UTF-8 text: byte {exc.start}") from None
    # nesting can be no deeper than the count of opening brackets: the character walk only
    # for texts with more than MAX_DEPTH of them (a jog's body has one)
    if data.count("[") + data.count("{") > MAX_DEPTH and _depth(data) > MAX_DEPTH:
        raise StrictJSONError(f"nested deeper than {MAX_DEPTH} levels")
    try:
        return json.loads(
            data, parse_constant=_refuse_constant, object_pairs_hook=_no_duplicates, parse_float=_finite_float
        )
    except StrictJSONError:
        raise
    except RecursionError:
        raise StrictJSONError(f"nested deeper than {MAX_DEPTH} levels") from None
    except ValueError as exc:
        raise StrictJSONError(str(exc).splitlines()[0][:200] if str(exc) else "not JSON") from None


def dumps_finite(obj: Any) -> str:
    """JSON text of ``obj``; non-finite floats (from a bad input echoed back) become strings."""

    def clean(value: Any) -> Any:
        if isinstance(value, float) and not math.isfinite(value):
            return repr(value)
        if isinstance(value, dict):
            return {str(k): clean(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [clean(v) for v in value]
        return value

    return json.dumps(clean(obj), allow_nan=False, default=str)
