"""The console's 3D state as messages of Foxglove's well-known JSON schemas.

A recording's 3D channels carry these, so that the MCAP file opens in Foxglove with the cell, the
virtual arm, the remote arm's ghost, the predicted path and the log drawn, with no setup:

* ``frame_transforms``: a ``foxglove.FrameTransforms`` with every link frame of one arm, by the
  robot model's forward kinematics: ``world -> {prefix}/base -> {prefix}/link1 -> ... ->
  {prefix}/link{dof} -> {prefix}/tool`` (the tool centre point). Each transform is the child's
  pose in its parent (``parent_T_child``).
* ``scene_update`` / ``object_entities``: a ``foxglove.SceneUpdate`` with one entity per cell
  object (in ``world``, at its pose) and one per arm link and prefix (in that link's frame,
  ``frame_locked``, so it follows the transforms). The remote arm is the console's translucent
  green ghost, the virtual arm has its robot file's link colours, as on the page.
* ``poses_in_frame``: a ``foxglove.PosesInFrame`` of the predicted tool path.
* ``log_message``: a ``foxglove.Log``.

Shapes: boxes, spheres and cylinders are Foxglove's own primitives; a capsule is a cylinder and
two spheres (exact, a few numbers instead of a thousand triangles); a mesh is a
``TriangleListPrimitive`` with indices (Foxglove draws these itself; no model loader involved),
vertex-clustered down to ``MAX_MESH_TRIANGLES`` when larger (the rover cell's terrain: 20k
triangles to under 5k), coordinates rounded to a micrometre. Mesh data is built once per file
and shared between messages: treat returned messages as read-only.

Everything returned is plain JSON data (dicts, lists, Python floats and ints). Units are SI
(metres); quaternions are Foxglove's ``(x, y, z, w)``, normalised. No I/O except reading the
schema files and the cell's mesh files.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Mapping, Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np
import pinocchio as pin

from shared.cells.cell import Cell
from shared.errors import FileFormatError, InputError, UnknownNameError
from shared.paths import ASSETS_DIR
from shared.robots.description import LinkShape
from shared.robots.model import Robot
from shared.robots.shapes import shape_mesh

#: the Foxglove schemas a recording uses, one file each in ``SCHEMA_DIR``
FOXGLOVE_SCHEMAS = ("foxglove.FrameTransforms", "foxglove.SceneUpdate", "foxglove.PosesInFrame", "foxglove.Log")
SCHEMA_DIR = ASSETS_DIR / "foxglove_schemas"
#: MCAP Schema record encoding of these schemas (the message encoding is "json")
SCHEMA_ENCODING = "jsonschema"

WORLD_FRAME = "world"
VIRTUAL_PREFIX = "virtual"
REMOTE_PREFIX = "remote"  # drawn as the ghost
#: foxglove.Log levels by name (the schema's LogLevel enum)
LOG_LEVELS = {"debug": 1, "info": 2, "warning": 3, "error": 4}
#: a mesh with more triangles than this is vertex-clustered down to at most this many
MAX_MESH_TRIANGLES = 5000
#: mesh vertex coordinates are rounded to this many decimals of a metre (1 um)
MESH_DECIMALS = 6


# -- schemas -----------------------------------------------------------------------------------
def schema_path(name: str, folder: str | Path | None = None) -> Path:
    if name not in FOXGLOVE_SCHEMAS:
        raise UnknownNameError("Foxglove schema", name, FOXGLOVE_SCHEMAS)
    return Path(folder if folder is not None else SCHEMA_DIR) / f"{name}.json"


def schema_bytes(name: str, folder: str | Path | None = None) -> bytes:
    """The schema file's text, for the data of MCAP's Schema record (encoding ``jsonschema``)."""
    path = schema_path(name, folder)
    try:
        return path.read_bytes()
    except OSError as exc:
        raise FileFormatError(path, f"cannot read the Foxglove schema: {exc.strerror or exc}") from None


# -- small pieces ------------------------------------------------------------------------------
def stamp(t_ns: int) -> dict:
    """A Foxglove ``time`` from nanoseconds since the Unix epoch."""
    t_ns = int(t_ns)
    if t_ns < 0:
        raise InputError(f"timestamp {t_ns} ns is before 1970; Foxglove times are not negative")
    sec, nsec = divmod(t_ns, 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


_FOREVER = {"sec": 0, "nsec": 0}  # an entity lifetime of zero: until replaced or deleted


def _shepperd_table() -> np.ndarray:
    """The four ways to read a quaternion off a rotation matrix, as one linear map ``(10, 16)``
    of ``[1, r00, r01, r02, r10, r11, r12, r20, r21, r22]`` to 4 ways x ``(x, y, z, w)`` up to scale."""
    index = {f"r{i}{j}": 1 + 3 * i + j for i in range(3) for j in range(3)}
    ways = [
        ["r21 - r12", "r02 - r20", "r10 - r01", "1 + r00 + r11 + r22"],  # from 4w^2
        ["1 + r00 - r11 - r22", "r01 + r10", "r02 + r20", "r21 - r12"],  # from 4x^2
        ["r01 + r10", "1 - r00 + r11 - r22", "r12 + r21", "r02 - r20"],  # from 4y^2
        ["r02 + r20", "r12 + r21", "1 - r00 - r11 + r22", "r10 - r01"],  # from 4z^2
    ]
    table = np.zeros((10, 16))
    for w, components in enumerate(ways):
        for c, text in enumerate(components):
            sign = 1.0
            for token in text.split():
                if token in "+-":
                    sign = 1.0 if token == "+" else -1.0
                else:
                    table[0 if token == "1" else index[token], 4 * w + c] = sign
    return table


_SHEPPERD = _shepperd_table()
_PIVOTS = np.array([3, 4, 9, 14])  # where each way's own square (4w^2, 4x^2, 4y^2, 4z^2) lands


def quaternions_xyzw(rotations: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(n, 4)`` as ``(x, y, z, w)`` with ``w >= 0`` of rotation matrices ``(n, 3, 3)``.

    Shepperd's method, vectorised: of the four ways to read a quaternion off the matrix, each row
    takes the one whose divisor is largest (no cancellation near 180-degree turns). One matrix
    product gives all four ways of every row (it runs on every arm change: keep it cheap).
    """
    r = np.asarray(rotations, dtype=float).reshape(-1, 9)
    n = len(r)
    ways = r @ _SHEPPERD[1:] + _SHEPPERD[0]  # (n, 16)
    best = np.argmax(ways[:, _PIVOTS], axis=1)
    q = ways.reshape(n, 4, 4)[np.arange(n), best]
    q *= np.copysign(1.0 / np.sqrt((q * q).sum(axis=1)), q[:, 3])[:, None]
    return q


def _vector(xyz: Sequence[float]) -> dict:
    return {"x": xyz[0], "y": xyz[1], "z": xyz[2]}


def _quaternion(xyzw: Sequence[float]) -> dict:
    return {"x": xyzw[0], "y": xyzw[1], "z": xyzw[2], "w": xyzw[3]}


def poses(transforms: np.ndarray) -> list[dict]:
    """Foxglove ``Pose`` dicts of poses ``(n, 4, 4)``."""
    transforms = np.asarray(transforms, dtype=float).reshape(-1, 4, 4)
    positions = transforms[:, :3, 3].tolist()
    rotations = quaternions_xyzw(transforms[:, :3, :3]).tolist()
    return [{"position": _vector(p), "orientation": _quaternion(r)} for p, r in zip(positions, rotations)]


def _colour(rgb: Sequence[int], alpha: float = 1.0) -> dict:
    return {"r": rgb[0] / 255.0, "g": rgb[1] / 255.0, "b": rgb[2] / 255.0, "a": float(alpha)}


def _pose_matrix(name: str, pose: object) -> np.ndarray:
    arr = np.asarray(pose, dtype=float)
    if arr.shape != (4, 4) or not np.all(np.isfinite(arr)):
        raise InputError(f"pose of object {name!r} must be a finite (4, 4) transform, got shape {arr.shape}")
    return arr


# -- frames of an arm --------------------------------------------------------------------------
def link_frame(prefix: str, link: int) -> str:
    """The frame of link ``link`` of the arm ``prefix``: link 0 is the robot's base."""
    return f"{prefix}/base" if link == 0 else f"{prefix}/link{link}"


def tool_frame(prefix: str) -> str:
    return f"{prefix}/tool"


@lru_cache(maxsize=64)
def _frame_names(prefix: str, dof: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    children = tuple(link_frame(prefix, i) for i in range(dof + 1)) + (tool_frame(prefix),)
    parents = (WORLD_FRAME,) + children[:-1]
    return parents, children


_link_T_tool_cache: dict[int, tuple[Robot, np.ndarray]] = {}


def _last_link_T_tool(robot: Robot) -> np.ndarray:
    """The robot's kinematic tool frame in its last link's frame: fixed, both ride on the last joint."""
    cached = _link_T_tool_cache.get(id(robot))
    if cached is not None and cached[0] is robot:
        return cached[1]
    data = robot.new_data()
    q = np.clip(np.zeros(robot.dof), robot.lower, robot.upper)
    pin.framesForwardKinematics(robot.model, data, q)
    last = data.oMf[robot.link_frame_ids[-1]]
    value = (last.inverse() * data.oMf[robot.tool_frame_id]).homogeneous.copy()
    _link_T_tool_cache[id(robot)] = (robot, value)
    return value


_local = threading.local()


def _own_data(robot: Robot):
    """This thread's pinocchio data for ``robot`` (the recorder's writer thread keeps its own)."""
    datas = getattr(_local, "datas", None)
    if datas is None:
        datas = _local.datas = {}
    entry = datas.get(id(robot))
    if entry is None or entry[0] is not robot:
        entry = datas[id(robot)] = (robot, robot.new_data())
    return entry[1]


_fixed_edges_cache: dict[tuple, tuple[Robot, np.ndarray]] = {}


def _fixed_edges(robot: Robot, world_T_base: np.ndarray, tool_T_tcp: np.ndarray | None) -> np.ndarray:
    """``(2, 7)``: translation and quaternion ``(x, y, z, w)`` of the two edges that do not move
    with ``q``: ``world_T_base`` and ``link{dof}_T_tcp`` (kept: they are the same on every call)."""
    world_T_base = np.asarray(world_T_base, dtype=float)
    tool = None if tool_T_tcp is None else np.asarray(tool_T_tcp, dtype=float)
    key = (id(robot), world_T_base.tobytes(), None if tool is None else tool.tobytes())
    cached = _fixed_edges_cache.get(key)
    if cached is not None and cached[0] is robot:
        return cached[1]
    link_T_tcp = _last_link_T_tool(robot)
    if tool is not None:
        link_T_tcp = link_T_tcp @ tool
    edges = np.stack([world_T_base, link_T_tcp])
    value = np.concatenate([edges[:, :3, 3], quaternions_xyzw(edges[:, :3, :3])], axis=1)
    if len(_fixed_edges_cache) > 64:
        _fixed_edges_cache.clear()
    _fixed_edges_cache[key] = (robot, value)
    return value


_joint_edges_cache: dict[int, tuple[Robot, tuple[int, ...]]] = {}


def _joint_edges(robot: Robot) -> tuple[int, ...]:
    """For each moving edge ``link{i-1}_T_link{i}``: the joint whose placement in its parent
    joint (pinocchio's ``liMi``) is that edge, where both links sit on their joints' frames and
    the joint hangs on the one before; 0 where not (the edge is then worked out from the poses)."""
    cached = _joint_edges_cache.get(id(robot))
    if cached is not None and cached[0] is robot:
        return cached[1]
    model, ids = robot.model, robot.link_frame_ids
    out = []
    for a, b in zip(ids[:-1], ids[1:]):
        fa, fb = model.frames[a], model.frames[b]
        joint = fb.parentJoint
        on_joints = fa.placement.isIdentity() and fb.placement.isIdentity()
        out.append(joint if joint > 0 and on_joints and model.parents[joint] == fa.parentJoint else 0)
    value = tuple(out)
    _joint_edges_cache[id(robot)] = (robot, value)
    return value


def _edges(robot: Robot, q, world_T_base: np.ndarray, tool_T_tcp: np.ndarray | None, data: pin.Data | None) -> np.ndarray:
    """``(dof + 2, 7)``: every edge of the arm's frame chain at ``q`` as translation and
    quaternion ``(x, y, z, w)``, ``w >= 0``: ``world_T_base``, ``link{i-1}_T_link{i}``, ``link{dof}_T_tcp``.

    It runs for every recorded arm pose: each moving edge is one pinocchio call on the link
    frames' poses (no 4x4 copies), the fixed edges are kept from the last call.
    """
    q = robot.as_q(q)
    d = data if data is not None else _own_data(robot)
    pin.framesForwardKinematics(robot.model, d, q)
    poses, joint_placements = d.oMf, d.liMi
    ids = robot.link_frame_ids
    # base_T_links[0] is the base itself (identity) and has no edge of its own: world_T_base is it
    edges = np.empty((len(ids) + 1, 7))
    edges[0], edges[-1] = _fixed_edges(robot, world_T_base, tool_T_tcp)
    for i, joint in enumerate(_joint_edges(robot), start=1):
        if joint:  # the two links are their joints' frames: the joint's placement is the edge
            edges[i] = pin.SE3ToXYZQUAT(joint_placements[joint])
        else:
            edges[i] = pin.SE3ToXYZQUAT(poses[ids[i - 1]].actInv(poses[ids[i]]))
    moving = edges[1:-1]
    moving[:, 3:] *= np.copysign(1.0, moving[:, 6:7])
    return edges


def frame_transforms(
    robot: Robot,
    q: np.ndarray | Sequence[float],
    world_T_base: np.ndarray,
    prefix: str,
    t_ns: int,
    *,
    tool_T_tcp: np.ndarray | None = None,
    data: pin.Data | None = None,
) -> dict:
    """A ``foxglove.FrameTransforms`` of every link of the arm at joint vector ``q`` (rad).

    Frames ``world -> {prefix}/base -> {prefix}/link1 ... {prefix}/link{dof} -> {prefix}/tool``;
    the tool frame is the tool centre point, ``tool_T_tcp`` from the robot's kinematic tool frame
    (``cell.flange_T_tcp``; identity: the kinematic tool frame itself). Each transform is the
    child's pose in its parent. ``data``: a pinocchio data of ``robot`` to reuse (default: one
    per thread, kept here).
    """
    edges = _edges(robot, q, world_T_base, tool_T_tcp, data)
    parents, children = _frame_names(prefix, len(edges) - 2)
    when = stamp(t_ns)
    return {
        "transforms": [
            {
                "timestamp": when,
                "parent_frame_id": parent,
                "child_frame_id": child,
                "translation": {"x": e[0], "y": e[1], "z": e[2]},
                "rotation": {"x": e[3], "y": e[4], "z": e[5], "w": e[6]},
            }
            for parent, child, e in zip(parents, children, edges.tolist())
        ]
    }


# -- shapes as primitives ----------------------------------------------------------------------
def cluster_vertices(vertices: np.ndarray, faces: np.ndarray, max_triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """Fewer triangles by vertex clustering: vertices in one cell of a grid merge (at their mean),
    triangles that collapse are dropped; the grid coarsens until at most ``max_triangles`` remain."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) <= max_triangles:
        return vertices, faces
    low = vertices.min(axis=0)
    extent = float(np.max(vertices.max(axis=0) - low)) or 1.0
    cell = extent / np.sqrt(max_triangles)  # a surface of side `extent` in cells of this size
    while True:
        keys = np.floor((vertices - low) / cell).astype(np.int64)
        _, cluster, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
        cluster = cluster.reshape(-1)
        merged = np.zeros((len(counts), 3))
        np.add.at(merged, cluster, vertices)
        merged /= counts[:, None]
        new_faces = cluster[faces]
        keep = (new_faces[:, 0] != new_faces[:, 1]) & (new_faces[:, 1] != new_faces[:, 2]) & (new_faces[:, 0] != new_faces[:, 2])
        new_faces = new_faces[keep]
        _, first = np.unique(np.sort(new_faces, axis=1), axis=0, return_index=True)
        new_faces = new_faces[np.sort(first)]
        if len(new_faces) <= max_triangles:
            used, remap = np.unique(new_faces, return_inverse=True)
            return merged[used], remap.reshape(-1, 3)
        cell *= 1.25


@lru_cache(maxsize=128)
def _mesh_triangles(mesh_path: str, scale: tuple[float, float, float]) -> tuple[list[dict], list[int]]:
    """A mesh file's points (in the shape's frame) and indices for a TriangleListPrimitive."""
    mesh = shape_mesh(LinkShape(kind="mesh", link_T_shape=np.eye(4), mesh_path=mesh_path, scale=scale))
    vertices, faces = _shared_vertices(mesh.vertices, mesh.faces)
    vertices, faces = _shared_vertices(*cluster_vertices(vertices, faces, MAX_MESH_TRIANGLES))
    return [_vector(v) for v in vertices.tolist()], faces.reshape(-1).tolist()


def _shared_vertices(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Round vertices to ``MESH_DECIMALS`` and let faces share equal ones (mesh files often
    repeat a vertex per face: three times the points), dropping faces that collapse."""
    rounded = np.round(np.asarray(vertices, dtype=float), MESH_DECIMALS)
    unique, inverse = np.unique(rounded, axis=0, return_inverse=True)
    faces = inverse.reshape(-1)[np.asarray(faces, dtype=np.int64)]
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    used, remap = np.unique(faces, return_inverse=True)
    return unique[used], remap.reshape(-1, 3)


def _shift_z(transform: np.ndarray, dz: float) -> np.ndarray:
    out = transform.copy()
    out[:3, 3] += transform[:3, 2] * dz
    return out


def _primitives(shapes: Iterable[LinkShape], frame_T_owner: np.ndarray | None, colour_of) -> dict[str, list]:
    """The entity's primitive lists for ``shapes`` (each posed by ``owner_T_shape``, the owner in
    the entity's frame at ``frame_T_owner``; None: the owner is the entity's frame)."""
    out: dict[str, list] = {"cubes": [], "spheres": [], "cylinders": [], "triangles": []}
    for shape in shapes:
        colour = colour_of(shape)
        at = shape.link_T_shape if frame_T_owner is None else frame_T_owner @ shape.link_T_shape
        if shape.kind == "box":
            out["cubes"].append({"pose": poses(at)[0], "size": _vector([float(s) for s in shape.size]), "color": colour})
        elif shape.kind == "sphere":
            d = 2.0 * float(shape.radius)
            out["spheres"].append({"pose": poses(at)[0], "size": _vector([d, d, d]), "color": colour})
        elif shape.kind in ("cylinder", "capsule"):
            d, length = 2.0 * float(shape.radius), float(shape.length)
            out["cylinders"].append({
                "pose": poses(at)[0], "size": _vector([d, d, length]),
                "bottom_scale": 1.0, "top_scale": 1.0, "color": colour,
            })
            if shape.kind == "capsule":  # the round ends: spheres at either end of the segment
                for end in poses(np.stack([_shift_z(at, -length / 2.0), _shift_z(at, length / 2.0)])):
                    out["spheres"].append({"pose": end, "size": _vector([d, d, d]), "color": colour})
        else:
            points, indices = _mesh_triangles(shape.mesh_path, tuple(float(s) for s in shape.scale))
            out["triangles"].append({"pose": poses(at)[0], "points": points, "color": colour, "colors": [], "indices": indices})
    return out


def _entity(entity_id: str, frame_id: str, t_ns: int, frame_locked: bool, metadata: dict[str, str], primitives: dict[str, list]) -> dict:
    return {
        "timestamp": stamp(t_ns),
        "frame_id": frame_id,
        "id": entity_id,
        "lifetime": dict(_FOREVER),
        "frame_locked": frame_locked,
        "metadata": [{"key": k, "value": v} for k, v in metadata.items()],
        "arrows": [],
        "cubes": primitives["cubes"],
        "spheres": primitives["spheres"],
        "cylinders": primitives["cylinders"],
        "lines": [],
        "triangles": primitives["triangles"],
        "texts": [],
        "models": [],
    }


def object_entity_id(name: str) -> str:
    return f"object/{name}"


def _object_entity_list(cell: Cell, object_poses: Mapping[str, np.ndarray], t_ns: int, names: Iterable[str] | None) -> list[dict]:
    unknown = [name for name in object_poses if name not in cell.object_names]
    if unknown:
        raise UnknownNameError("object", unknown[0], cell.object_names)
    wanted = cell.object_names if names is None else tuple(names)
    entities = []
    for name in wanted:
        obj = cell.object(name)
        pose = _pose_matrix(name, object_poses.get(name, obj.world_T_object))
        colour = _colour(obj.color)
        entities.append(_entity(
            object_entity_id(name), WORLD_FRAME, t_ns, False, {"object": name},
            _primitives(obj.shapes, pose, lambda _shape: colour),
        ))
    return entities


def _arm_colour_of(robot: Robot, link: int, prefix: str):
    """How the page colours link ``link`` of arm ``prefix``: the ghost's green, or the robot
    file's colour of the link's first shape for the whole link (``webui.scene``)."""
    if prefix == REMOTE_PREFIX:
        from webui.ghost import GHOST_COLOR, GHOST_OPACITY  # the page's own ghost (imports viser: only here)

        ghost = _colour(GHOST_COLOR, GHOST_OPACITY)
        return lambda _shape: ghost
    shapes = robot.shapes.get(link, ())
    solid = _colour(shapes[0].color) if shapes else _colour((200, 200, 200))
    return lambda _shape: solid


def arm_entity_id(prefix: str, link: int) -> str:
    return link_frame(prefix, link)


def _arm_entity_list(robot: Robot, prefix: str, t_ns: int) -> list[dict]:
    entities = []
    for link in range(robot.dof + 1):
        shapes = robot.shapes.get(link, ())
        if not shapes:
            continue
        entities.append(_entity(
            arm_entity_id(prefix, link), link_frame(prefix, link), t_ns, True,
            {"arm": prefix, "link": str(link)}, _primitives(shapes, None, _arm_colour_of(robot, link, prefix)),
        ))
    return entities


def object_entities(
    cell: Cell, object_poses: Mapping[str, np.ndarray], t_ns: int, names: Iterable[str] | None = None,
) -> dict:
    """A ``foxglove.SceneUpdate`` of the cell's objects alone (``names``: only those), each in
    ``world`` at its pose in ``object_poses`` (``world_T_object``) or the cell file's pose.
    Entities keep their ids, so sending this again when an object moves replaces them."""
    return {"deletions": [], "entities": _object_entity_list(cell, object_poses, t_ns, names)}


def scene_update(
    cell: Cell,
    object_poses: Mapping[str, np.ndarray],
    t_ns: int,
    prefixes: Sequence[str] = (VIRTUAL_PREFIX, REMOTE_PREFIX),
) -> dict:
    """A ``foxglove.SceneUpdate`` of the whole scene: the cell's objects (as ``object_entities``)
    and, for each arm prefix, one entity per link with shapes, in that link's frame
    (``frame_transforms`` with the same prefix places it); the ``remote`` arm is the ghost."""
    entities = _object_entity_list(cell, object_poses, t_ns, None)
    for prefix in prefixes:
        entities.extend(_arm_entity_list(cell.robot, prefix, t_ns))
    return {"deletions": [], "entities": entities}


# -- path and log ------------------------------------------------------------------------------
_IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


def poses_in_frame(points_world: np.ndarray | Sequence[Sequence[float]], t_ns: int, frame_id: str = WORLD_FRAME) -> dict:
    """A ``foxglove.PosesInFrame`` of the path's points ``(n, 3)`` (m), identity orientations."""
    points = np.asarray(points_world, dtype=float)
    if points.size == 0:
        points = points.reshape(0, 3)
    if points.ndim != 2 or points.shape[1] != 3 or not np.all(np.isfinite(points)):
        raise InputError(f"path points must be finite and of shape (n, 3), got shape {points.shape}")
    return {
        "timestamp": stamp(t_ns),
        "frame_id": frame_id,
        "poses": [{"position": _vector(p), "orientation": dict(_IDENTITY)} for p in points.tolist()],
    }


def log_message(t_ns: int, level: str, message: str, name: str) -> dict:
    """A ``foxglove.Log``: ``level`` one of debug, info, warning, error; ``name`` who says it."""
    if level not in LOG_LEVELS:
        raise UnknownNameError("log level", level, LOG_LEVELS)
    return {
        "timestamp": stamp(t_ns),
        "level": LOG_LEVELS[level],
        "message": str(message),
        "name": str(name),
        "file": "",
        "line": 0,
    }
