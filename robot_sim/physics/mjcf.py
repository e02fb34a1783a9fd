"""The cell as a MuJoCo model: the arm from the console's own robot model, the cell's objects as
bodies, a two-finger gripper with a wrist force/torque sensor.

Nothing here is a hand-written copy of the robot: the chain is read from the pinocchio model the
console uses (each joint's placement and axis), the collision shapes from the robot's link table,
the cell's objects from the cell. What the robot file cannot say comes from elsewhere:

* link inertias: ``dynamics.toml`` beside the robot file when it exists (the PUMA's published
  values), otherwise MuJoCo computes them from the link shapes at ``link_density``;
* the gripper: the last link's shapes are split at the wrist sensor. The shapes that straddle the
  tool point sideways (the finger boxes of the link table) become two finger bodies on slide
  joints, closing towards the tool axis with at most ``grip_force`` each; the rest of the last
  link's shapes (flange, palm) is the gripper body the sensor carries;
* movable objects (the pegs) are free bodies at ``object_density``, their foot chamfered at 45
  degrees by ``chamfer`` (a convex mesh), and made narrower or wider so that their fit in a hole
  is ``clearance`` when one is asked for.

Collision groups: the static cell collides with the arm, the fingers and the objects; the arm's
links never collide with each other (the console's interference zones keep them apart, and the
simplified shapes overlap at every joint); the objects collide with everything.
"""

from __future__ import annotations

import logging
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from shared.cells.physics import PhysicsParams
from shared.cells.cell import Cell, CellObject
from shared.errors import FileFormatError
from shared.robots.description import LinkShape
from shared.terrain.cell import TERRAIN_OBJECT

log = logging.getLogger(__name__)

# collision bits (contype / conaffinity)
_STATIC, _ARM, _OBJECT, _FINGER = 1, 2, 4, 8
STATIC_BIT = _STATIC
UNMODELLED_GEOM = "unmodelled/0"
"""The spare geom a fault puts into the cell as an obstacle or a jam (its label: ``unmodelled``)."""


@dataclass(frozen=True)
class LinkInertia:
    mass: float
    com: tuple[float, float, float]
    inertia: tuple[float, float, float]
    armature: float = 0.0


@dataclass
class ModelLayout:
    """What the world needs to know about the model it was built with."""

    xml: str
    dof: int
    finger_travel: float  # how far each finger can close (m)
    finger_open_gap: float  # between the pads when open (m)
    objects: list[str] = field(default_factory=list)  # movable objects, one free body each
    object_half: dict[str, np.ndarray] = field(default_factory=dict)  # half extents as built
    inertia_source: str = ""


def _fmt(values) -> str:
    return " ".join(f"{float(v):.10g}" for v in np.ravel(values))


def _quat(R: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of a rotation matrix."""
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def _pose_attrs(T: np.ndarray) -> str:
    return f'pos="{_fmt(T[:3, 3])}" quat="{_fmt(_quat(T[:3, :3]))}"'


def _geom(shape: LinkShape, T: np.ndarray, name: str, extra: str, meshes: list[str]) -> str:
    """One shape as a geom posed by ``T`` in its body."""
    if shape.kind == "box":
        size = f'type="box" size="{_fmt(np.asarray(shape.size) / 2.0)}"'
    elif shape.kind == "sphere":
        size = f'type="sphere" size="{shape.radius:.10g}"'
    elif shape.kind == "cylinder":
        size = f'type="cylinder" size="{shape.radius:.10g} {shape.length / 2.0:.10g}"'
    elif shape.kind == "capsule":
        size = f'type="capsule" size="{shape.radius:.10g} {shape.length / 2.0:.10g}"'
    else:
        from shared.robots.shapes import shape_mesh

        mesh = shape_mesh(shape)
        meshes.append(f'<mesh name="{name}_mesh" vertex="{_fmt(mesh.vertices)}" face="{_fmt(mesh.faces)}"/>')
        size = f'type="mesh" mesh="{name}_mesh"'
    rgba = _fmt([*np.asarray(shape.color) / 255.0, 1.0])
    return f'<geom name="{name}" {size} {_pose_attrs(T)} rgba="{rgba}" {extra}/>'


def load_link_inertias(robot_source: str, dof: int) -> tuple[list[LinkInertia] | None, str]:
    """The published inertias in ``dynamics.toml`` beside the robot file, or None."""
    path = Path(robot_source).with_name("dynamics.toml")
    if not path.is_file():
        return None, ""
    try:
        with path.open("rb") as f:
            data = tomllib.load(f)
        links = [LinkInertia(float(d["mass"]), tuple(map(float, d["com"])), tuple(map(float, d["inertia"])),
                             float(d.get("armature", 0.0))) for d in data["links"]]
    except (OSError, tomllib.TOMLDecodeError, KeyError, TypeError, ValueError) as exc:
        raise FileFormatError(str(path), f"cannot read the link inertias: {exc}") from None
    if len(links) != dof:
        raise FileFormatError(str(path), f"has {len(links)} links, the robot {dof}")
    for i, link in enumerate(links, start=1):
        if not link.mass > 0.0 or min(link.inertia) <= 0.0 or link.armature < 0.0:
            raise FileFormatError(str(path), f"link {i}: mass and inertias must be > 0 and armature >= 0")
    return links, str(data.get("source", path.name))


def _is_finger(shape: LinkShape, flange_T_tcp: np.ndarray) -> bool:
    """A box of the last link that reaches the tool point's height beside the tool axis."""
    if shape.kind != "box":
        return False
    centre = shape.link_T_shape[:3, 3]
    half = np.abs(shape.link_T_shape[:3, :3]) @ (np.asarray(shape.size) / 2.0)
    tcp = flange_T_tcp[:3, 3]
    lateral = np.hypot(centre[0] - tcp[0], centre[1] - tcp[1])
    return abs(centre[2] - tcp[2]) <= half[2] and lateral > max(half[0], half[1]) * 0.5 and lateral > 1e-3


def chamfered_box(half: np.ndarray, chamfer: float) -> np.ndarray:
    """Vertices of a box with its bottom edges chamfered at 45 degrees (a convex hull)."""
    hx, hy, hz = (float(v) for v in half)
    c = min(chamfer, 0.45 * min(hx, hy), 0.45 * hz)
    top = [(sx * hx, sy * hy, hz) for sx in (-1, 1) for sy in (-1, 1)]
    if c <= 0.0:
        bottom = [(sx * hx, sy * hy, -hz) for sx in (-1, 1) for sy in (-1, 1)]
        return np.array(top + bottom)
    shoulder = [(sx * hx, sy * hy, -hz + c) for sx in (-1, 1) for sy in (-1, 1)]
    foot = [(sx * (hx - c), sy * (hy - c), -hz) for sx in (-1, 1) for sy in (-1, 1)]
    return np.array(top + shoulder + foot)


def build_mjcf(cell: Cell, params: PhysicsParams, object_poses: dict[str, np.ndarray],
               object_half: dict[str, np.ndarray]) -> ModelLayout:
    """The MJCF text of ``cell`` with the movable objects at ``object_poses`` (world frame) and
    with the half extents ``object_half`` (their fit in the holes)."""
    robot = cell.robot
    model = robot.model
    dof = robot.dof
    inertias, inertia_source = load_link_inertias(robot.description.source, dof)
    p = params
    solref = f'solref="{p.contact_timeconst:.6g} {p.contact_dampratio:.6g}"'
    meshes: list[str] = []
    world: list[str] = []

    # -- the static cell -------------------------------------------------------------------------
    for obj in cell.objects:
        if obj.movable:
            continue
        if obj.name == TERRAIN_OBJECT:
            # the ground as a height field built from the same point cloud (robot_sim.physics.terrain)
            from robot_sim.physics.terrain import terrain_geoms

            assets, geoms = terrain_geoms(cell, obj, friction=p.friction, contype=_STATIC)
            meshes += assets
            world += geoms
            continue
        for k, shape in enumerate(obj.shapes):
            T = obj.world_T_object @ shape.link_T_shape
            world.append(_geom(shape, T, f"{obj.name}/{k}", f'contype="{_STATIC}" conaffinity="0" '
                               f'friction="{p.friction:.6g} 0.005 0.0001" group="0"', meshes))

    # the unmodelled thing a fault campaign puts into the cell (``robot_sim.physics.faults``): a box
    # far below the cell, colliding with nothing until a fault gives it a place and a size
    world.append(f'<geom name="{UNMODELLED_GEOM}" type="box" size="0.02 0.02 0.02" pos="0 0 -100" contype="0" '
                 f'conaffinity="0" group="3" rgba="0.9 0.1 0.1 1" friction="{p.friction:.6g} 0.005 0.0001"/>')

    # -- the arm -----------------------------------------------------------------------------------
    arm_extra = f'contype="{_ARM}" conaffinity="{_STATIC}" group="1" friction="{p.friction:.6g} 0.005 0.0001"'
    last_shapes = robot.shapes.get(dof, ())
    fingers = [s for s in last_shapes if _is_finger(s, cell.flange_T_tcp)]
    palm = [s for s in last_shapes if not any(s is f for f in fingers)]
    if len(fingers) != 2:
        log.warning("the robot's last link has %d finger boxes, not 2: the physics gripper cannot hold objects",
                    len(fingers))
    base_T_chain = cell.world_T_base
    body_open: list[str] = [f'<body name="base" {_pose_attrs(base_T_chain)}>']
    for k, shape in enumerate(robot.shapes.get(0, ())):
        body_open.append(_geom(shape, shape.link_T_shape, f"link0/{k}", arm_extra, meshes))
    closers = ["</body>"]
    tcp = cell.flange_T_tcp
    finger_travel = 0.0
    open_gap = 0.0
    for i in range(1, dof + 1):
        placement = model.jointPlacements[i].homogeneous
        jmodel = model.joints[i]
        axis = np.array([0.0, 0.0, 1.0])
        if "Unaligned" in jmodel.shortname():
            axis = np.array(jmodel.extract().axis if hasattr(jmodel.extract(), "axis") else [0, 0, -1.0])
        elif jmodel.shortname().endswith("RX"):
            axis = np.array([1.0, 0.0, 0.0])
        elif jmodel.shortname().endswith("RY"):
            axis = np.array([0.0, 1.0, 0.0])
        lo, hi = robot.lower[i - 1], robot.upper[i - 1]
        lines = [f'<body name="link{i}" {_pose_attrs(placement)} gravcomp="1">']
        if inertias is not None:
            li = inertias[i - 1]
            lines.append(f'<inertial pos="{_fmt(li.com)}" mass="{li.mass:.6g}" diaginertia="{_fmt(li.inertia)}"/>')
            armature = li.armature
        else:
            armature = 0.05
        lines.append(f'<joint name="j{i}" type="hinge" axis="{_fmt(axis)}" range="{lo:.10g} {hi:.10g}" '
                     f'armature="{armature:.6g}" damping="0" limited="true"/>')
        shapes = robot.shapes.get(i, ()) if i < dof else ()
        density = "" if inertias is not None else f'density="{p.link_density:.6g}"'
        for k, shape in enumerate(shapes):
            extra = arm_extra + (' mass="0"' if inertias is not None else f" {density}")
            lines.append(_geom(shape, shape.link_T_shape, f"link{i}/{k}", extra, meshes))
        if i == dof:
            # the wrist sensor at the flange: everything beyond it is the gripper
            # the sensor's body is welded to the flange; the gripper hangs from it on the
            # compliant wrist: sideways springs and tilting springs about a centre near the
            # fingertips, as a remote-centre compliance device carries a gripper
            centre = tcp[:3, 3] + tcp[:3, 2] * p.compliance_centre
            lateral_damping = 2.0 * np.sqrt(p.compliance_lateral * 0.6)
            travel = f'limited="true" range="{-p.compliance_travel:.6g} {p.compliance_travel:.6g}"'
            angular_damping = 2.0 * np.sqrt(p.compliance_angular * 0.6 * 0.06 ** 2)
            lines.append('<body name="wrist" gravcomp="1"><site name="wrist" size="0.005"/>'
                         '<inertial pos="0 0 0" mass="0.01" diaginertia="1e-6 1e-6 1e-6"/>')
            lines.append('<body name="gripper" gravcomp="1">')
            if p.compliance_lateral > 0.0:
                for axis in ("1 0 0", "0 1 0"):
                    lines.append(f'<joint type="slide" axis="{axis}" stiffness="{p.compliance_lateral:.6g}" '
                                 f'damping="{lateral_damping:.6g}" armature="0.05" {travel}/>')
            if p.compliance_axial > 0.0:
                axial_damping = 2.0 * np.sqrt(p.compliance_axial * 0.6)
                lines.append(f'<joint type="slide" axis="{_fmt(tcp[:3, 2])}" stiffness="{p.compliance_axial:.6g}" '
                             f'damping="{axial_damping:.6g}" armature="0.05" {travel}/>')
            if p.compliance_angular > 0.0:
                for axis in ("1 0 0", "0 1 0"):
                    lines.append(f'<joint type="hinge" axis="{axis}" pos="{_fmt(centre)}" '
                                 f'stiffness="{p.compliance_angular:.6g}" damping="{angular_damping:.6g}" '
                                 f'armature="0.002" limited="true" range="{-p.compliance_tilt:.6g} {p.compliance_tilt:.6g}"/>')
            lines.append(f'<site name="tcp" {_pose_attrs(tcp)} size="0.003"/>')
            for k, shape in enumerate(palm):
                lines.append(_geom(shape, shape.link_T_shape, f"gripper/{k}",
                                   arm_extra + f' density="{p.link_density:.6g}"', meshes))
            for k, shape in enumerate(fingers):
                centre = shape.link_T_shape[:3, 3]
                inward = tcp[:3, 3] - centre
                inward[2] = 0.0
                dist = float(np.linalg.norm(inward))
                inward /= dist
                half = np.abs(shape.link_T_shape[:3, :3]) @ (np.asarray(shape.size) / 2.0)
                pad = float(abs(inward @ half))  # half thickness towards the axis
                finger_travel = dist - pad
                open_gap = 2.0 * (dist - pad)
                lines.append(f'<body name="finger{k}" {_pose_attrs(shape.link_T_shape)} gravcomp="1">')
                local_axis = shape.link_T_shape[:3, :3].T @ inward
                lines.append(f'<joint name="finger{k}" type="slide" axis="{_fmt(local_axis)}" '
                             f'range="0 {finger_travel:.6g}" armature="0.01" damping="5"/>')
                lines.append(f'<geom name="finger{k}/pad" type="box" size="{_fmt(np.asarray(shape.size) / 2.0)}" '
                             f'mass="{p.finger_mass:.6g}" contype="{_FINGER}" conaffinity="{_STATIC | _OBJECT}" condim="4" group="1" '
                             f'friction="{p.finger_friction:.6g} {p.torsional_friction:.6g} 0.0001" '
                             f'rgba="{_fmt([*np.asarray(shape.color) / 255.0, 1.0])}"/>')
                lines.append("</body>")
            lines.append("</body></body>")
        body_open += lines
        closers.append("</body>")
    world += body_open + closers[::-1]

    # -- the movable objects ----------------------------------------------------------------------
    objects = []
    for obj in cell.objects:
        if not obj.movable:
            continue
        objects.append(obj.name)
        T = object_poses[obj.name]
        lines = [f'<body name="{obj.name}" {_pose_attrs(T)}><freejoint name="{obj.name}"/>']
        lines += _object_geoms(obj, object_half[obj.name], p, meshes)
        lines.append("</body>")
        world += lines

    actuators = []
    for i in range(1, dof + 1):
        lo, hi = robot.lower[i - 1], robot.upper[i - 1]
        # gains are set by the world from the arm's inertia once the model is compiled
        actuators.append(f'<general name="servo{i}" joint="j{i}" gaintype="fixed" biastype="affine" '
                         f'gainprm="1" biasprm="0 -1 -0.1" ctrlrange="{lo - 1:.10g} {hi + 1:.10g}" '
                         f'forcerange="{-p.max_joint_torque:.6g} {p.max_joint_torque:.6g}"/>')
        actuators.append(f'<motor name="feedforward{i}" joint="j{i}" gear="1" ctrlrange="-100 100" '
                         f'forcerange="{-p.max_joint_torque:.6g} {p.max_joint_torque:.6g}"/>')
    equality = []
    if len(fingers) == 2:
        # a parallel gripper: one motor, the fingers geared to close together (centred on the tool axis)
        actuators.append(f'<position name="grip0" joint="finger0" kp="20000" kv="40" '
                         f'ctrlrange="0 {finger_travel:.6g}" forcerange="{-p.grip_force:.6g} {p.grip_force:.6g}"/>')
        equality.append('<joint joint1="finger1" joint2="finger0" polycoef="0 1 0 0 0" solref="0.002 1" solimp="0.99 0.999 0.0001"/>')

    sensors = ['<force name="wrist_force" site="wrist"/>', '<torque name="wrist_torque" site="wrist"/>']
    xml = "\n".join([
        f"<mujoco model={quoteattr(cell.name)}>",
        '<compiler angle="radian" autolimits="true" balanceinertia="true"/>',
        f'<option timestep="{p.timestep:.6g}" integrator="implicitfast" gravity="0 0 -9.81" cone="elliptic" '
        f'impratio="5"><flag multiccd="enable" autoreset="disable"/></option>',
        f'<default><geom {solref} solimp="0.95 0.99 0.0002 0.5 2"/></default>',
        "<asset>", *meshes, "</asset>",
        "<worldbody>", *world, "</worldbody>",
        "<actuator>", *actuators, "</actuator>",
        "<equality>", *equality, "</equality>",
        "<sensor>", *sensors, "</sensor>",
        "</mujoco>",
    ])
    return ModelLayout(xml=xml, dof=dof, finger_travel=finger_travel, finger_open_gap=open_gap, objects=objects,
                       object_half=dict(object_half), inertia_source=inertia_source or f"link shapes at {p.link_density:g} kg/m^3")


def _object_geoms(obj: CellObject, half: np.ndarray, p: PhysicsParams, meshes: list[str]) -> list[str]:
    """A movable object's collision: its one box as a chamfered convex mesh, other shapes as they are."""
    out = []
    extra = (f'contype="{_OBJECT}" conaffinity="{_STATIC | _ARM | _OBJECT | _FINGER}" group="2" density="{p.object_density:.6g}" '
             f'condim="4" friction="{p.friction:.6g} {p.torsional_friction:.6g} 0.0001"')
    for k, shape in enumerate(obj.shapes):
        if k == 0 and shape.kind == "box":
            name = f"{obj.name}/{k}"
            vertices = chamfered_box(half, p.chamfer)
            meshes.append(f'<mesh name="{name}_mesh" vertex="{_fmt(vertices)}"/>')
            rgba = _fmt([*np.asarray(shape.color) / 255.0, 1.0])
            out.append(f'<geom name="{name}" type="mesh" mesh="{name}_mesh" {_pose_attrs(shape.link_T_shape)} '
                       f'rgba="{rgba}" {extra}/>')
        else:
            out.append(_geom(shape, shape.link_T_shape, f"{obj.name}/{k}", extra, meshes))
    return out
