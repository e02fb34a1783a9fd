"""Text units of the statement language and their exact conversion to SI.

The text form is what a person reads (mm, deg, %, mm/s, deg/s, N, s); the models hold SI
(m, rad, fraction, m/s, rad/s, N, s). A program must survive text -> JSON -> text -> JSON with
the same JSON, so every conversion here is a pure function of the decimal *text* and the
formatter searches for a text that this very function maps back to the same float:

* mm, %, mm/s are decimal shifts: ``"12.5" mm`` is the decimal 0.0125 m, rounded once to the
  nearest float. The reverse is exact too: the shortest repr of the float, shifted back.
* deg and deg/s: a text of at most 15 significant digits converts as ``math.radians`` (and
  ``numpy.radians``) do, so ``30 deg`` is exactly ``math.radians(30)`` and values made with
  numpy print short. A float multiplication skips some floats, though, so a text of 16 or more
  significant digits is multiplied by pi/180 in 40-digit decimal arithmetic and rounded once;
  every float is reachable that way, and the formatter widens precision until it maps back.
* N and s are plain decimal numbers.
"""

from __future__ import annotations

import decimal
import math
from decimal import Decimal
from enum import Enum

_CTX = decimal.Context(prec=40, Emax=999_999, Emin=-999_999, traps=[decimal.InvalidOperation])
_PI = Decimal("3.14159265358979323846264338327950288419716939937510")
_DEG = _CTX.divide(_PI, Decimal(180))  # rad per deg, 40 digits
_RAD = _CTX.divide(Decimal(180), _PI)  # deg per rad, 40 digits


class TextUnit(str, Enum):
    """A unit as written in the text form; the value is its canonical spelling."""

    MM = "mm"
    DEG = "deg"
    PERCENT = "%"
    MM_PER_S = "mm/s"
    DEG_PER_S = "deg/s"
    NEWTON = "N"
    SECOND = "s"


_BY_SPELLING = {u.value.lower(): u for u in TextUnit}


def unit_from_text(text: str) -> TextUnit | None:
    """The unit a token spells (case-insensitive), or ``None``."""
    return _BY_SPELLING.get(text.lower())


class ConversionError(ValueError):
    """A number that has no finite SI value (too large, or not a number at all)."""


def _finite(value: float) -> float:
    if not math.isfinite(value):
        raise ConversionError("number is too large")
    return value


def significant_digits(text: str) -> int:
    """Significant digits of a decimal text, trailing zeros included (``"30.00"`` has 4)."""
    mantissa = text.lstrip("+-").split("e")[0].split("E")[0].replace(".", "")
    return len(mantissa.lstrip("0"))


def to_si(text: str, unit: TextUnit) -> float:
    """The SI float of the decimal ``text`` written in ``unit`` (exact, rounded once)."""
    try:
        d = Decimal(text)
        if unit in (TextUnit.MM, TextUnit.MM_PER_S):
            d = d.scaleb(-3, _CTX)
        elif unit is TextUnit.PERCENT:
            d = d.scaleb(-2, _CTX)
        elif unit in (TextUnit.DEG, TextUnit.DEG_PER_S):
            if significant_digits(text) <= 15:
                degrees = float(text)
                if math.isfinite(degrees):
                    return _finite(math.radians(degrees))
            d = _CTX.multiply(d, _DEG)
        return _finite(float(d))
    except (decimal.DecimalException, ValueError, OverflowError) as exc:
        if isinstance(exc, ConversionError):
            raise
        raise ConversionError("number is out of range") from None


def _plain(d: Decimal) -> str:
    """A readable decimal spelling: fixed point for ordinary magnitudes, exponent otherwise."""
    if d.is_zero():
        return "-0" if d.is_signed() else "0"
    d = d.normalize(_CTX)
    exp = d.adjusted()
    if -7 <= exp <= 15:
        s = format(d, "f")
    else:
        s = format(d, "e").replace("e+", "e")
    return s


def _wide(d: Decimal, digits: int) -> str:
    """``d`` written with exactly ``digits`` significant digits (trailing zeros kept)."""
    if d.is_zero():
        return "0"
    exp = d.adjusted()
    if -7 <= exp <= 15:
        return format(d, f".{max(digits - 1 - exp, 0)}f")
    return format(d, f".{digits - 1}e").replace("e+", "e")


def from_si(value: float, unit: TextUnit) -> str:
    """A decimal text for ``value`` in ``unit`` that :func:`to_si` maps back to exactly ``value``."""
    if not math.isfinite(value):
        raise ConversionError(f"cannot write {value!r} as a number")
    if unit in (TextUnit.MM, TextUnit.MM_PER_S, TextUnit.PERCENT):
        shift = 2 if unit is TextUnit.PERCENT else 3
        return _plain(Decimal(repr(value)).scaleb(shift, _CTX))
    if unit in (TextUnit.NEWTON, TextUnit.SECOND):
        return _plain(Decimal(repr(value)))
    # degrees: the shortest repr of math.degrees first, then wider decimals of the exact value
    degrees = math.degrees(value)
    if math.isfinite(degrees):
        candidate = _plain(Decimal(repr(degrees)))
        if significant_digits(candidate) <= 15 and to_si(candidate, unit) == value:
            return candidate
        for digits in range(1, 16):
            candidate = _plain(Decimal(format(degrees, f".{digits}g")))
            if to_si(candidate, unit) == value:
                return candidate
    exact = _CTX.multiply(Decimal(value), _RAD)
    for digits in range(16, 41):
        rounded = decimal.Context(prec=digits).plus(exact)
        candidate = _wide(rounded, digits)
        if to_si(candidate, unit) == value:
            return candidate
    raise ConversionError(f"no decimal text maps back to {value!r} rad")  # not reached in practice
