"""Load a robot by built-in name or from a file (robot TOML or URDF) into a ``Robot``.

Built-in robots live in ``assets/robots/<name>/robot.toml``. A ``.urdf`` path is loaded with
pinocchio; its tool frame is the last link of the chain unless named. Errors name the file and
the field; every number is finite and within the bounds of ``shared.robots.file_numbers``
(sizes above zero, colours 0..255).
"""

from __future__ import annotations

import functools
import tomllib
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from shared.errors import FileFormatError, UnknownNameError
from shared.paths import ASSETS_DIR
from shared.robots.description import DHJoint, LinkShape, RobotDescription
from shared.robots.file_numbers import RGB, Angle, Length, Rpy, Scale3, Size, Size3, Vec3, file_error, units_context
from shared.robots.model import Robot, build_dh_model
from shared.spatial import pose_to_transform

ROBOTS_DIR = ASSETS_DIR / "robots"

_LENGTH_SCALE = {"m": 1.0, "mm": 1e-3}
_ANGLE_SCALE = {"rad": 1.0, "deg": np.pi / 180.0}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class _JointSpec(_Strict):
    a: Length
    alpha: Angle
    d: Length
    offset: Angle = 0.0
    sign: Literal[1, -1] = 1
    limits: tuple[Angle, Angle]
    name: str = ""

    @field_validator("limits")
    @classmethod
    def _ordered(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError(f"lower limit {v[0]} must be below upper limit {v[1]}")
        return v


class _ToolSpec(_Strict):
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Rpy = (0.0, 0.0, 0.0)


class _KinematicsSpec(_Strict):
    convention: Literal["modified", "standard"]
    length_unit: Literal["m", "mm"] = "m"
    angle_unit: Literal["rad", "deg"] = "rad"
    joints: list[_JointSpec] = Field(min_length=1)
    tool: _ToolSpec = _ToolSpec()
    base: _ToolSpec = _ToolSpec()  # pose of the chain's first DH frame in the base frame
    # how far past a joint limit (angle_unit) an IK solution may fall and still be taken, at the limit
    ik_limit_tolerance: float | None = Field(default=None, ge=0.0, allow_inf_nan=False)


class _ShapeSpec(_Strict):
    link: int = Field(ge=0)
    shape: Literal["box", "sphere", "cylinder", "capsule", "mesh"]
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Rpy = (0.0, 0.0, 0.0)
    size: Size3 | None = None
    radius: Size | None = None
    length: Size | None = None
    mesh: str | None = None
    scale: Scale3 = (1.0, 1.0, 1.0)
    color: RGB = (200, 200, 200)


class _RobotFile(_Strict):
    name: str
    description: str = ""
    ik: Literal["puma", "rover", "dls"] = "dls"
    kinematics: _KinematicsSpec
    geometry: list[_ShapeSpec] = []
    always_in_contact: list[tuple[int, int]] = []
    fit: dict = {}


def _shape_from_spec(spec: _ShapeSpec, index: int, path: Path, ls: float, as_: float, dof: int) -> LinkShape:
    where = f"geometry[{index}]"
    if spec.link > dof:
        raise FileFormatError(path, f"link {spec.link} does not exist (robot has links 0..{dof})", where + ".link")
    return shape_from_spec(spec, where, path, ls, as_, color=spec.color)


def shape_from_spec(spec, where: str, path: Path, ls: float, as_: float, color: tuple[int, int, int] | None = None) -> LinkShape:
    """A ``LinkShape`` (SI) from a file's shape table (``shape``, ``xyz``, ``rpy``, ``size``,
    ``radius``, ``length``, ``mesh``, ``scale`` in the file's units ``ls``/``as_`` per unit);
    a missing dimension or mesh file is a ``FileFormatError`` naming ``where``. Robot and cell
    files share it."""
    needs = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length"), "capsule": ("radius", "length"), "mesh": ("mesh",)}
    for attr in needs[spec.shape]:
        if getattr(spec, attr) is None:
            raise FileFormatError(path, f"a {spec.shape} needs '{attr}'", f"{where}.{attr}")
    mesh_path = ""
    if spec.mesh is not None:
        mesh_file = (path.parent / spec.mesh).resolve()
        if mesh_file.is_dir():
            raise FileFormatError(path, f"{mesh_file} is a folder, not a mesh file", f"{where}.mesh")
        if not mesh_file.is_file():
            raise FileFormatError(path, f"mesh file {mesh_file} does not exist", f"{where}.mesh")
        mesh_path = str(mesh_file)
    extra = {} if color is None else {"color": color}
    return LinkShape(
        kind=spec.shape,
        link_T_shape=pose_to_transform(np.array(spec.xyz) * ls, np.array(spec.rpy) * as_),
        size=tuple(float(v) * ls for v in spec.size) if spec.size else (0.0, 0.0, 0.0),
        radius=(spec.radius or 0.0) * ls,
        length=(spec.length or 0.0) * ls,
        mesh_path=mesh_path,
        scale=spec.scale,
        **extra,
    )


def load_description(path: Path) -> RobotDescription:
    """Read and validate a robot TOML file into a ``RobotDescription`` (SI units)."""
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileFormatError(path, "file does not exist") from None
    except IsADirectoryError:
        raise FileFormatError(path, "is a folder, not a robot file") from None
    except UnicodeDecodeError:
        raise FileFormatError(path, "not a UTF-8 text file") from None
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(path, f"not valid TOML: {exc}") from None
    kin_raw = raw.get("kinematics") if isinstance(raw.get("kinematics"), dict) else {}
    context = units_context(kin_raw.get("length_unit", "m"), kin_raw.get("angle_unit", "rad"))
    try:
        spec = _RobotFile.model_validate(raw, context=context)
    except ValidationError as exc:
        raise file_error(path, exc) from None
    kin = spec.kinematics
    ls, as_ = _LENGTH_SCALE[kin.length_unit], _ANGLE_SCALE[kin.angle_unit]
    joints = tuple(
        DHJoint(
            a=j.a * ls, alpha=j.alpha * as_, d=j.d * ls, offset=j.offset * as_, sign=j.sign,
            lower=j.limits[0] * as_, upper=j.limits[1] * as_, name=j.name or f"joint{i + 1}",
        )
        for i, j in enumerate(kin.joints)
    )
    shapes: dict[int, list[LinkShape]] = {}
    for index, s in enumerate(spec.geometry):
        shapes.setdefault(s.link, []).append(_shape_from_spec(s, index, path, ls, as_, len(joints)))
    for a, b in spec.always_in_contact:
        if not (0 <= a <= len(joints) and 0 <= b <= len(joints)):
            raise FileFormatError(path, f"pair ({a}, {b}) names a link that does not exist", "always_in_contact")
    return RobotDescription(
        name=spec.name,
        source=str(path),
        convention=kin.convention,
        joints=joints,
        flange_T_tool=pose_to_transform(np.array(kin.tool.xyz) * ls, np.array(kin.tool.rpy) * as_),
        base_T_chain=pose_to_transform(np.array(kin.base.xyz) * ls, np.array(kin.base.rpy) * as_),
        **({} if kin.ik_limit_tolerance is None else {"ik_limit_tolerance": kin.ik_limit_tolerance * as_}),
        ik=spec.ik,
        shapes={k: tuple(v) for k, v in shapes.items()},
        always_in_contact=tuple((int(a), int(b)) for a, b in spec.always_in_contact),
        link_names=tuple(["base"] + [f"link{i}" for i in range(1, len(joints) + 1)]),
    )


def builtin_robot_names() -> list[str]:
    return sorted(p.parent.name for p in ROBOTS_DIR.glob("*/robot.toml"))


def _load_uncached(ref: str) -> Robot:
    path = Path(ref)
    if path.suffix.lower() == ".urdf":
        from shared.robots.urdf import load_urdf_robot

        return load_urdf_robot(path)
    if path.suffix.lower() == ".toml":
        desc = load_description(path)
    else:
        candidate = ROBOTS_DIR / ref / "robot.toml"
        if not candidate.is_file():
            raise UnknownNameError("robot", ref, builtin_robot_names() + ["<file>.urdf", "<file>.toml"])
        desc = load_description(candidate)
    model, tool_id, link_ids = build_dh_model(desc)
    return Robot(desc, model, tool_id, link_ids)


@functools.lru_cache(maxsize=32)
def _load_cached(key: str) -> Robot:
    return _load_uncached(key)


def load_robot(ref: str | Path) -> Robot:
    """Load a robot by built-in name (``puma562``, ``rover``) or a ``.toml``/``.urdf`` path.

    Models are immutable and cached: loading the same reference twice returns the same object.
    """
    key = str(ref)
    p = Path(key)
    if p.suffix.lower() in (".urdf", ".toml"):
        key = str(p.resolve())
    return _load_cached(key)
