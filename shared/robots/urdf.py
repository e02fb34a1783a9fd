"""Load any serial arm described by a URDF file into a ``Robot``.

The file is read and checked here first (with ``xml.etree``) so that a broken file gets one
clear line naming the file and what is wrong; pinocchio's URDF parser would otherwise print
several lines of its own to stderr and raise an uninformative error. The checked document is
then handed to ``pinocchio.buildModelFromXML``, which builds the kinematic model.

How a URDF maps onto the ``Robot`` interface (the same as for DH robots):

* base frame: the URDF root link (``base_T_tool`` and ``link_poses`` are in that frame);
* joint ``i`` (1..dof): the ``i``-th movable joint along the chain from the root; the movable
  joints must form one serial chain. ``continuous`` joints become revolute joints with the
  range [-2 pi, 2 pi] (one variable per joint, as the interface needs); prismatic, planar,
  floating and mimic joints are refused;
* link ``i``: the child link of joint ``i`` (its frame is the joint frame); link 0 is the root.
  Links attached by fixed joints belong to the moving link they hang from;
* tool frame: ``tool_link`` when given, else the last link in file order that hangs rigidly
  from the last moving link (``tool0`` for the UR5), or the last moving link itself;
* shapes: the ``<collision>`` geometry of every link (box, sphere, cylinder, mesh), posed in
  its moving link's frame and coloured like the link's visual material; used both for
  collision and for display;
* inverse kinematics: damped least squares (``ik = "dls"``).
"""

from __future__ import annotations

import copy
import logging
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

from shared.errors import FileFormatError
from shared.language.bounds import MAX_ANGLE_RAD, WORKSPACE_M
from shared.robots.description import LinkShape, RobotDescription, UrdfJoint
from shared.robots.model import Robot
from shared.spatial import pose_to_transform

log = logging.getLogger(__name__)

#: range given to a ``continuous`` joint (rad): two turns, like the UR joints
CONTINUOUS_RANGE = (-2.0 * math.pi, 2.0 * math.pi)
#: colour of shapes whose link has no visual material colour
DEFAULT_COLOR = (200, 200, 200)

_MOVABLE = ("revolute", "continuous")
_REFUSED = ("prismatic", "planar", "floating")


def _floats(
    path: Path, text: str | None, count: int, field: str, default: tuple[float, ...] | None = None,
    bound: float | None = None, unit: str = "m",
) -> tuple[float, ...]:
    """Parse ``count`` whitespace-separated finite numbers from an attribute, each at most
    ``bound`` in magnitude when given (``unit`` spells it in the message)."""
    if text is None:
        if default is None:
            raise FileFormatError(path, "attribute is missing", field)
        return default
    try:
        values = tuple(float(v) for v in text.split())
    except ValueError:
        raise FileFormatError(path, f"expected {count} numbers, got {text!r}", field) from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise FileFormatError(path, f"expected {count} finite numbers, got {text[:80]!r}", field)
    if bound is not None and any(abs(v) > bound for v in values):
        raise FileFormatError(path, f"{text[:80]!r} is beyond the bound of \u00b1{bound:g} {unit}", field)
    return values


def _origin(path: Path, element: ET.Element, field: str) -> np.ndarray:
    """The ``<origin xyz rpy>`` of an element as a 4x4 transform (identity when absent)."""
    origin = element.find("origin")
    if origin is None:
        return np.eye(4)
    xyz = _floats(path, origin.get("xyz"), 3, f"{field} origin xyz", (0.0, 0.0, 0.0), WORKSPACE_M, "m")
    rpy = _floats(path, origin.get("rpy"), 3, f"{field} origin rpy", (0.0, 0.0, 0.0), MAX_ANGLE_RAD, "rad")
    return pose_to_transform(np.array(xyz), np.array(rpy))  # URDF rpy is fixed-axis X, Y, Z


def _resolve_mesh(path: Path, uri: str, field: str | None = None) -> Path | None:
    """Find a mesh named by a URDF: a path relative to the URDF's folder, an absolute path, a
    ``file://`` URI, or ``package://<pkg>/<rest>`` looked up in the URDF's parent folders."""
    if uri.startswith("file://"):
        uri = uri[len("file://"):]
    if uri.startswith("package://"):
        package, _, rest = uri[len("package://"):].partition("/")
        for folder in [path.parent, *path.parent.parents]:
            candidates = [folder / package / rest] + ([folder / rest] if folder.name == package else [])
            for candidate in candidates:
                if candidate.is_file():
                    return candidate.resolve()
        return None
    candidate = Path(uri) if Path(uri).is_absolute() else path.parent / uri
    if candidate.is_dir():
        raise FileFormatError(path, f"mesh {uri!r} is a folder, not a mesh file", field)
    return candidate.resolve() if candidate.is_file() else None


def _material_colors(path: Path, root: ET.Element) -> dict[str, tuple[int, int, int]]:
    out: dict[str, tuple[int, int, int]] = {}
    for material in root.findall("material"):
        color = material.find("color")
        if material.get("name") and color is not None and color.get("rgba"):
            rgba = _rgba(path, color.get("rgba", ""), f"material {material.get('name', '')!r} color rgba")
            if rgba is not None:
                out[material.get("name", "")] = rgba
    return out


def _rgba(path: Path, text: str, field: str) -> tuple[int, int, int] | None:
    """RGB in 0..255 from a URDF ``rgba`` (four numbers in 0..1); None when it is not four
    numbers (the link keeps the default colour); refused when a number is outside 0..1."""
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        return None
    if len(values) != 4:
        return None
    if not all(0.0 <= v <= 1.0 for v in values):  # NaN fails too
        raise FileFormatError(path, f"{text[:80]!r}: each of r, g, b, a must be in 0..1", field)
    return tuple(int(round(255 * v)) for v in values[:3])  # type: ignore[return-value]


def _link_color(path: Path, link: ET.Element, materials: dict[str, tuple[int, int, int]]) -> tuple[int, int, int]:
    """The colour of a link's first visual material, so collision shapes look like the arm."""
    for visual in link.findall("visual"):
        material = visual.find("material")
        if material is None:
            continue
        color = material.find("color")
        if color is not None:
            rgba = _rgba(path, color.get("rgba", ""), f"link {link.get('name', '')!r} visual material rgba")
            if rgba is not None:
                return rgba
        if material.get("name") in materials:
            return materials[material.get("name", "")]
    return DEFAULT_COLOR


def _collision_shapes(
    path: Path, link: ET.Element, link_T_frame: np.ndarray, color: tuple[int, int, int]
) -> list[LinkShape]:
    """The ``<collision>`` shapes of one URDF link, posed in its moving link's frame."""
    name = link.get("name", "")
    out: list[LinkShape] = []
    for k, collision in enumerate(link.findall("collision")):
        field = f"link {name!r} collision {k}"
        geometry = collision.find("geometry")
        if geometry is None or len(geometry) == 0:
            raise FileFormatError(path, "has no <geometry>", field)
        shape = geometry[0]
        pose = link_T_frame @ _origin(path, collision, field)
        if shape.tag == "box":
            size = _floats(path, shape.get("size"), 3, f"{field} box size", bound=WORKSPACE_M)
            out.append(LinkShape("box", pose, size=size, color=color))  # type: ignore[arg-type]
        elif shape.tag == "sphere":
            (radius,) = _floats(path, shape.get("radius"), 1, f"{field} sphere radius", bound=WORKSPACE_M)
            out.append(LinkShape("sphere", pose, radius=radius, color=color))
        elif shape.tag == "cylinder":
            (radius,) = _floats(path, shape.get("radius"), 1, f"{field} cylinder radius", bound=WORKSPACE_M)
            (length,) = _floats(path, shape.get("length"), 1, f"{field} cylinder length", bound=WORKSPACE_M)
            out.append(LinkShape("cylinder", pose, radius=radius, length=length, color=color))
        elif shape.tag == "mesh":
            uri = shape.get("filename")
            if not uri:
                raise FileFormatError(path, "a <mesh> needs a filename", field)
            mesh_file = _resolve_mesh(path, uri, field)
            if mesh_file is None:
                raise FileFormatError(path, f"mesh file {uri!r} not found (relative paths are read from {path.parent})", field)
            scale = _floats(path, shape.get("scale"), 3, f"{field} mesh scale", (1.0, 1.0, 1.0), 1e6, "")
            out.append(LinkShape("mesh", pose, mesh_path=str(mesh_file), scale=scale, color=color))  # type: ignore[arg-type]
        else:
            raise FileFormatError(path, f"unknown geometry <{shape.tag}> (box, sphere, cylinder or mesh)", field)
        made = out[-1]
        dims = {"box": made.size, "sphere": (made.radius,), "cylinder": (made.radius, made.length), "mesh": made.scale}
        if min(dims[shape.tag]) <= 0.0:
            raise FileFormatError(path, f"{shape.tag} dimensions must be positive", field)
    return out


def _kinematics_only(root: ET.Element) -> ET.Element:
    """A copy of the document with only named links and the kinematic parts of the joints."""
    out = ET.Element("robot", {"name": root.get("name", "robot")})
    for element in root:
        if element.tag == "link":
            ET.SubElement(out, "link", {"name": element.get("name", "")})
        elif element.tag == "joint":
            joint = ET.SubElement(out, "joint", dict(element.attrib))
            keep = ("parent", "child", "origin") + (("axis", "limit") if element.get("type") != "fixed" else ())
            for part in element:
                if part.tag in keep:
                    joint.append(copy.deepcopy(part))
    return out


def _read_document(path: Path) -> ET.Element:
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        raise FileFormatError(path, "file does not exist") from None
    except IsADirectoryError:
        raise FileFormatError(path, "is a directory, not a URDF file") from None
    except OSError as exc:
        raise FileFormatError(path, f"cannot read file: {exc.strerror}") from None
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise FileFormatError(path, f"not valid XML: {exc}") from None
    if root.tag != "robot":
        raise FileFormatError(path, f"the top element is <{root.tag}>, a URDF needs <robot>")
    return root


def load_urdf_robot(path: str | Path, tool_link: str | None = None) -> Robot:
    """Build a ``Robot`` (pinocchio model, joint ranges, collision shapes, DLS inverse
    kinematics) from a URDF file. ``tool_link`` names the link whose frame is the tool; see the
    module docstring for the default. Raises ``FileFormatError`` naming the file and the fault."""
    path = Path(path)
    root = _read_document(path)

    links: dict[str, ET.Element] = {}
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            raise FileFormatError(path, "a <link> has no name")
        if name in links:
            raise FileFormatError(path, f"link {name!r} is defined twice")
        links[name] = link
    if not links:
        raise FileFormatError(path, "has no <link> elements")

    joint_of_child: dict[str, ET.Element] = {}
    children: dict[str, list[str]] = {name: [] for name in links}
    joint_names: set[str] = set()
    for joint in root.findall("joint"):
        name = joint.get("name")
        if not name:
            raise FileFormatError(path, "a <joint> has no name")
        if name in joint_names:
            raise FileFormatError(path, f"joint {name!r} is defined twice")
        joint_names.add(name)
        field = f"joint {name!r}"
        kind = joint.get("type")
        if kind in _REFUSED:
            raise FileFormatError(path, f"is {kind}; only revolute, continuous and fixed joints are supported", field)
        if kind not in (*_MOVABLE, "fixed"):
            raise FileFormatError(path, f"unknown joint type {kind!r}", field)
        if kind in _MOVABLE and joint.find("mimic") is not None:
            raise FileFormatError(path, "mimic joints are not supported", field)
        _origin(path, joint, field)  # checks the numbers before pinocchio reads them
        ends = {}
        for end in ("parent", "child"):
            element = joint.find(end)
            ref = element.get("link") if element is not None else None
            if not ref:
                raise FileFormatError(path, f"needs <{end} link=...>", field)
            if ref not in links:
                raise FileFormatError(path, f"{end} link {ref!r} is not defined", field)
            ends[end] = ref
        if ends["child"] in joint_of_child:
            raise FileFormatError(path, f"link {ends['child']!r} is the child of two joints", field)
        joint_of_child[ends["child"]] = joint
        children[ends["parent"]].append(ends["child"])

    roots = [name for name in links if name not in joint_of_child]
    if len(roots) != 1:
        what = "no root link (the joints form a loop)" if not roots else f"{len(roots)} root links ({', '.join(roots)})"
        raise FileFormatError(path, f"has {what}; a URDF must be one tree")
    root_link = roots[0]

    # walk the tree from the root (depth first, children in file order, as pinocchio does)
    order: list[str] = []
    moving_parent: dict[str, str | None] = {root_link: None}  # link -> child link of the nearest movable joint above
    stack = [root_link]
    while stack:
        link_name = stack.pop()
        order.append(link_name)
        for child in reversed(children[link_name]):
            joint = joint_of_child[child]
            moving_parent[child] = child if joint.get("type") in _MOVABLE else moving_parent[link_name]
            stack.append(child)
    if len(order) != len(links):
        raise FileFormatError(path, "some links are not connected to the root link")

    # the movable joints must form one chain: each one's nearest movable ancestor is the previous
    chain: list[ET.Element] = []
    above: str | None = None
    movable = [joint_of_child[l] for l in order if l in joint_of_child and joint_of_child[l].get("type") in _MOVABLE]
    if not movable:
        raise FileFormatError(path, "has no revolute or continuous joints (nothing to move)")
    for joint in movable:
        parent_link = joint.find("parent").get("link")  # type: ignore[union-attr]
        if moving_parent[parent_link] != above:
            raise FileFormatError(
                path, f"the movable joints branch at joint {joint.get('name')!r}; teleprog needs one serial chain"
            )
        chain.append(joint)
        above = joint.find("child").get("link")  # type: ignore[union-attr]
    last_moving = above

    # joint ranges; continuous joints become revolute with a two-turn range
    urdf_joints: list[UrdfJoint] = []
    for joint in chain:
        name = joint.get("name", "")
        field = f"joint {name!r}"
        limit = joint.find("limit")
        if joint.get("type") == "continuous":
            joint.set("type", "revolute")
            if limit is None:
                limit = ET.SubElement(joint, "limit")
            limit.set("lower", repr(CONTINUOUS_RANGE[0]))
            limit.set("upper", repr(CONTINUOUS_RANGE[1]))
        if limit is None or limit.get("lower") is None or limit.get("upper") is None:
            raise FileFormatError(path, "a revolute joint needs <limit lower=... upper=...>", field)
        (lower,) = _floats(path, limit.get("lower"), 1, f"{field} limit lower", bound=MAX_ANGLE_RAD, unit="rad")
        (upper,) = _floats(path, limit.get("upper"), 1, f"{field} limit upper", bound=MAX_ANGLE_RAD, unit="rad")
        if not lower < upper:
            raise FileFormatError(path, f"limit lower {lower} must be below upper {upper}", field)
        for attr in ("effort", "velocity"):  # required by pinocchio's parser, unused here
            limit.set(attr, limit.get(attr) or "0")
        axis_element = joint.find("axis")
        axis_text = axis_element.get("xyz") if axis_element is not None else None
        axis = _floats(path, axis_text, 3, f"{field} axis xyz", (1.0, 0.0, 0.0))  # URDF default: x
        if np.linalg.norm(axis) < 1e-9:
            raise FileFormatError(path, "axis xyz must not be zero", field)
        urdf_joints.append(
            UrdfJoint(
                name=name, lower=lower, upper=upper, axis=axis,  # type: ignore[arg-type]
                parent_link=joint.find("parent").get("link", ""),  # type: ignore[union-attr]
                child_link=joint.find("child").get("link", ""),  # type: ignore[union-attr]
            )
        )

    # tool link
    if tool_link is None:
        rigid = {l for l in order if moving_parent[l] == last_moving}
        tool_link = [l for l in links if l in rigid][-1]  # last in file order
    elif tool_link not in links:
        raise FileFormatError(path, f"tool link {tool_link!r} is not a link of this file (links: {', '.join(links)})", "tool_link")

    # pinocchio builds the kinematic model from the checked links and joints alone: geometry,
    # inertia, materials, gazebo and transmission tags are left out so that its parser has
    # nothing unchecked to complain about on stderr (teleprog reads collision shapes itself)
    xml = ET.tostring(_kinematics_only(root), encoding="unicode")
    try:
        model = pin.buildModelFromXML(xml)
    except Exception as exc:  # pinocchio raises ValueError/RuntimeError with several lines
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise FileFormatError(path, f"pinocchio cannot build a model: {first}") from None
    if model.nq != len(chain) or model.nv != len(chain):
        raise FileFormatError(path, f"pinocchio made {model.nq} joint variables for {len(chain)} joints")
    for i, joint in enumerate(chain, start=1):
        if model.names[i] != joint.get("name"):
            raise FileFormatError(path, f"joint order differs from pinocchio's ({model.names[i]} at {i})")

    def body_frame(link_name: str) -> int:
        if link_name == root_link:
            return 0  # the universe frame: pinocchio puts the root link there
        return model.getFrameId(link_name, pin.FrameType.BODY)

    tool_id = body_frame(tool_link)
    link_frame_ids = (0,) + tuple(body_frame(j.child_link) for j in urdf_joints)

    materials = _material_colors(path, root)
    shapes: dict[int, list[LinkShape]] = {}
    for link_name, link in links.items():
        frame_id = body_frame(link_name)
        frame = model.frames[frame_id]
        index = int(frame.parentJoint)  # joint i moves link i
        link_T_frame = frame.placement.homogeneous if frame_id else np.eye(4)
        found = _collision_shapes(path, link, link_T_frame, _link_color(path, link, materials))
        if found:
            shapes.setdefault(index, []).extend(found)

    name = root.get("name") or path.stem
    model.name = name
    description = RobotDescription(
        name=name,
        source=str(path),
        convention=None,
        joints=tuple(urdf_joints),
        flange_T_tool=np.eye(4),
        ik="dls",
        shapes={k: tuple(v) for k, v in shapes.items()},
        urdf_path=str(path.resolve()),
        urdf_tool_frame=tool_link,
        link_names=(root_link, *(j.child_link for j in urdf_joints)),
    )
    log.debug("loaded URDF robot %s from %s: %d joints, tool %s", name, path, len(chain), tool_link)
    return Robot(description, model, tool_id, link_frame_ids)
