"""Numbers of robot and cell files, checked: finite, within physical bounds, sizes above zero.

Both file formats (robot TOML, cell TOML) declare their units once (``mm``/``m``, ``deg``/
``rad``), and the field types here check each value *in SI* against the bounds of
``shared.language.bounds``, so a cell in millimetres and one in metres are held to the same
workspace. The file's units reach the validators through pydantic's validation context
(:func:`units_context`). An error names the field the way the file spells it
(``objects[2].shapes[0].size``, see :func:`field_path`).
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import AfterValidator, Field, ValidationError, ValidationInfo
from pydantic_core import PydanticCustomError

from shared.errors import FileFormatError
from shared.language.bounds import MAX_ANGLE_RAD, WORKSPACE_M, describe

_LENGTH_SCALE = {"m": 1.0, "mm": 1e-3}
_ANGLE_SCALE = {"rad": 1.0, "deg": math.pi / 180.0}

MAX_MESH_SCALE = 1e6
"""Largest scale factor of a mesh (a mesh in micrometres scaled to metres is 1e-6; the other
way round 1e6)."""
MAX_PIXELS = 1e7
"""Largest focal length or principal-point coordinate of a camera (pixels)."""


def units_context(length_unit: object, angle_unit: object) -> dict[str, Any]:
    """The validation context for a file in these units (unknown spellings fall back to SI;
    the unit fields themselves refuse them with their own message)."""
    length = length_unit if length_unit in _LENGTH_SCALE else "m"
    angle = angle_unit if angle_unit in _ANGLE_SCALE else "rad"
    return {"length_unit": length, "length_scale": _LENGTH_SCALE[length],
            "angle_unit": angle, "angle_scale": _ANGLE_SCALE[angle]}


def _bounded(kind: str, limit_si: float, what: str):
    def check(v: float, info: ValidationInfo) -> float:
        ctx = info.context or {}
        scale = ctx.get(f"{kind}_scale", 1.0)
        if abs(v * scale) > limit_si:
            unit = ctx.get(f"{kind}_unit", "m" if kind == "length" else "rad")
            raise PydanticCustomError(
                "out_of_bounds", "{value} {unit} is beyond the {what} of \u00b1{limit} {unit}",
                {"value": describe(v), "unit": unit, "what": what, "limit": describe(limit_si / scale)},
            )
        return v

    return AfterValidator(check)


Length = Annotated[float, _bounded("length", WORKSPACE_M, "workspace bound")]
"""A coordinate in the file's length unit, within the workspace bound."""
Size = Annotated[float, Field(gt=0), _bounded("length", WORKSPACE_M, "workspace bound")]
"""A box edge, radius or length: above zero, within the workspace bound."""
Angle = Annotated[float, _bounded("angle", MAX_ANGLE_RAD, "angle bound")]
"""An angle in the file's angle unit, at most two turns either way."""
Scale = Annotated[float, Field(gt=0, le=MAX_MESH_SCALE)]
Pixels = Annotated[float, Field(ge=-MAX_PIXELS, le=MAX_PIXELS)]
Channel = Annotated[int, Field(ge=0, le=255)]

Vec3 = tuple[Length, Length, Length]
Rpy = tuple[Angle, Angle, Angle]
Size3 = tuple[Size, Size, Size]
Scale3 = tuple[Scale, Scale, Scale]
RGB = tuple[Channel, Channel, Channel]
"""A colour: red, green, blue in 0..255."""


def field_path(loc: tuple[Any, ...]) -> str:
    """A pydantic location as the file spells it: ``("objects", 2, "size")`` -> ``objects[2].size``."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def file_error(path: object, exc: ValidationError) -> FileFormatError:
    """The first error of a file's validation, naming the file and the field."""
    first = exc.errors()[0]
    return FileFormatError(path, str(first.get("msg", "invalid")), field_path(tuple(first.get("loc", ()))))
