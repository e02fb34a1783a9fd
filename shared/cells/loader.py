"""Read a cell file (TOML) into a ``Cell``; every error names the file and the field.

Every number is checked (``shared.robots.file_numbers``): finite, within the workspace and
angle bounds in SI whatever the file's units, sizes and radii above zero, colours 0..255,
camera intrinsics in range; feature kinds are ``point`` or ``hole``. Fields are named as the
file spells them: ``objects[2].shapes[0].size``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from shared.cells.cell import Cell, CellObject, Feature, ZoneDistances
from shared.cells.physics import parse_physics
from shared.errors import FileFormatError, TeleprogError
from shared.paths import ASSETS_DIR, CELLS_DIR, DEFAULT_CELL  # noqa: F401 - DEFAULT_CELL is also read from here
from shared.robots.file_numbers import RGB, Angle, Pixels, Rpy, Scale3, Size, Size3, Vec3, file_error, units_context
from shared.robots.loader import load_robot, shape_from_spec
from shared.spatial import pose_to_transform
from shared.vision.camera import Camera


_LENGTH_SCALE = {"m": 1.0, "mm": 1e-3}
_ANGLE_SCALE = {"rad": 1.0, "deg": np.pi / 180.0}

FEATURE_KINDS = ("point", "hole")
"""What a feature may be: a plain point, or a hole mouth (its z axis out of the hole)."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class _Units(_Strict):
    length: Literal["m", "mm"] = "m"
    angle: Literal["rad", "deg"] = "rad"


class _Pose(_Strict):
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Rpy = (0.0, 0.0, 0.0)


class _RobotSpec(_Pose):
    ref: str
    q_home: list[Angle] | None = None
    tcp: _Pose = _Pose()


class _FrameSpec(_Pose):
    relative_to: str = "world"


class _ShapeSpec(_Pose):
    shape: Literal["box", "sphere", "cylinder", "capsule", "mesh"]
    size: Size3 | None = None
    radius: Size | None = None
    length: Size | None = None
    mesh: str | None = None
    scale: Scale3 = (1.0, 1.0, 1.0)


class _ObjectSpec(_Pose):
    name: str = Field(min_length=1)
    frame: str = "world"
    movable: bool = False
    held: bool = False
    color: RGB = (180, 180, 180)
    shapes: list[_ShapeSpec] = Field(min_length=1)
    keypoints: list[Vec3] = []


class _FeatureSpec(_Pose):
    name: str = Field(min_length=1)
    frame: str = "world"
    kind: Literal["point", "hole"] = "point"


class _ZoneSpec(_Strict):
    quasi: Size
    operation: Size


class _CameraSpec(_Pose):
    """A calibrated camera: pose (its +z is the optical axis, image v runs along +y) and the
    pinhole intrinsics in pixels."""

    name: str = Field(min_length=1)
    frame: str = "world"
    fx: Pixels = Field(gt=0)
    fy: Pixels = Field(gt=0)
    cx: Pixels
    cy: Pixels
    width: int = Field(gt=0, le=100_000)
    height: int = Field(gt=0, le=100_000)


class _CellFile(_Strict):
    name: str
    description: str = ""
    units: _Units = _Units()
    robot: _RobotSpec
    frames: dict[str, _FrameSpec] = {}
    objects: list[_ObjectSpec] = []
    features: list[_FeatureSpec] = []
    cameras: list[_CameraSpec] = []
    zones: _ZoneSpec = _ZoneSpec(quasi=100.0, operation=20.0)
    zone_overrides: dict[str, _ZoneSpec] = {}
    physics: dict[str, object] | None = None  # checked by shared.cells.physics, its keys carry their units


def load_cell(path: str | Path) -> Cell:
    """Load and validate a cell file."""
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileFormatError(path, "file does not exist") from None
    except IsADirectoryError:
        raise FileFormatError(path, "is a folder, not a cell file") from None
    except UnicodeDecodeError:
        raise FileFormatError(path, "not a text file") from None
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(path, f"not valid TOML: {exc}") from None
    units_raw = raw.get("units") if isinstance(raw.get("units"), dict) else {}
    context = units_context(units_raw.get("length", "m"), units_raw.get("angle", "rad"))
    try:
        spec = _CellFile.model_validate(raw, context=context)
    except ValidationError as exc:
        raise file_error(path, exc) from None

    ls, as_ = _LENGTH_SCALE[spec.units.length], _ANGLE_SCALE[spec.units.angle]

    def pose(p: _Pose) -> np.ndarray:
        return pose_to_transform(np.array(p.xyz) * ls, np.array(p.rpy) * as_)

    ref = spec.robot.ref
    if ref.endswith((".urdf", ".toml")):
        ref = str((path.parent / ref).resolve())
    try:
        robot = load_robot(ref)
    except TeleprogError as exc:
        raise FileFormatError(path, str(exc), "robot.ref") from None

    frames: dict[str, np.ndarray] = {"world": np.eye(4), "base": pose(spec.robot)}
    for name, fspec in spec.frames.items():
        if name in ("world", "base", "tool"):
            raise FileFormatError(path, f"frame {name!r} is built in and cannot be redefined", f"frames.{name}")
        if fspec.relative_to not in frames:
            raise FileFormatError(
                path, f"relative_to {fspec.relative_to!r} is not a frame defined above; valid: {', '.join(frames)}",
                f"frames.{name}.relative_to",
            )
        frames[name] = frames[fspec.relative_to] @ pose(fspec)
    frames.setdefault("work", np.eye(4))

    q_home = np.zeros(robot.dof)
    if spec.robot.q_home is not None:
        if len(spec.robot.q_home) != robot.dof:
            raise FileFormatError(path, f"robot {robot.name!r} has {robot.dof} joints, q_home has {len(spec.robot.q_home)}", "robot.q_home")
        q_home = np.array(spec.robot.q_home) * as_
        if not robot.within_limits(q_home):
            raise FileFormatError(path, "q_home is outside the robot's joint ranges", "robot.q_home")

    objects: list[CellObject] = []
    for i, ospec in enumerate(spec.objects):
        where = f"objects[{i}]"
        if ospec.name in (o.name for o in objects):
            raise FileFormatError(path, f"object name {ospec.name!r} is used twice", f"{where}.name")
        if ospec.frame not in frames:
            raise FileFormatError(path, f"frame {ospec.frame!r} is not defined; valid: {', '.join(frames)}", f"{where}.frame")
        shapes = tuple(shape_from_spec(s, f"{where}.shapes[{k}]", path, ls, as_) for k, s in enumerate(ospec.shapes))
        objects.append(
            CellObject(
                name=ospec.name, world_T_object=frames[ospec.frame] @ pose(ospec), shapes=shapes,
                movable=ospec.movable, held=ospec.held, color=ospec.color,
                keypoints=np.array(ospec.keypoints, dtype=float).reshape(-1, 3) * ls,
            )
        )
    features: dict[str, Feature] = {}
    for i, fspec in enumerate(spec.features):
        if fspec.frame not in frames:
            raise FileFormatError(path, f"frame {fspec.frame!r} is not defined; valid: {', '.join(frames)}", f"features[{i}].frame")
        features[fspec.name] = Feature(fspec.name, frames[fspec.frame] @ pose(fspec), fspec.kind)

    cameras: dict[str, Camera] = {}
    for i, cspec in enumerate(spec.cameras):
        if cspec.frame not in frames:
            raise FileFormatError(path, f"frame {cspec.frame!r} is not defined; valid: {', '.join(frames)}", f"cameras[{i}].frame")
        if cspec.name in cameras:
            raise FileFormatError(path, f"camera name {cspec.name!r} is used twice", f"cameras[{i}].name")
        cameras[cspec.name] = Camera.pinhole(cspec.name, cspec.fx, cspec.fy, cspec.cx, cspec.cy,
                                             frames[cspec.frame] @ pose(cspec), cspec.width, cspec.height)

    def zones(z: _ZoneSpec, where: str) -> ZoneDistances:
        if not z.operation < z.quasi:
            raise FileFormatError(path, f"operation distance {z.operation} must be below quasi distance {z.quasi}", where)
        return ZoneDistances(quasi=z.quasi * ls, operation=z.operation * ls)

    overrides = {}
    for name, z in spec.zone_overrides.items():
        if name not in (o.name for o in objects):
            raise FileFormatError(path, f"no object named {name!r}", f"zone_overrides.{name}")
        overrides[name] = zones(z, f"zone_overrides.{name}")
    return Cell(
        name=spec.name,
        source=str(path),
        robot=robot,
        world_T_base=frames["base"],
        q_home=q_home,
        flange_T_tcp=pose(spec.robot.tcp),
        frames=frames,
        objects=tuple(objects),
        features=features,
        zones=zones(spec.zones, "zones"),
        zone_overrides=overrides,
        description=spec.description,
        cameras=cameras,
        physics=parse_physics(spec.physics, str(path)),
    )
