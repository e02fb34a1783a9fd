"""Where the 3D view's camera stands for a cell: a default that frames the work, and presets.

Computed from the cell, never written into it. The points the view must hold (``work_focus``)
are what the cell's task is about: the holes and other features, the objects the arm may move,
the fixtures that carry a feature (the plate with the holes, not the table under it), and the
gripper at the home pose. A cell without such things (an arm over a terrain, an arm alone) is
framed by the arm at home and the part of each object within the arm's reach (the ground it can
touch, not the whole 2 m field).

The direction (``front_direction``): the task's main points lie along a line (HOLE1 to HOLE2,
the transfer); the default camera looks *across* it from above at ``FRONT_ELEVATION``, so none
hides another, from the base's side and turned just enough to keep the arm's links off the line
of sight. With no such line the camera stands three-quarters in front of the arm. The distance
(``fit``) makes the focus fill a set share of the view's narrower side (``FILL_TASK`` round a
task's small objects, ``FILL_SCENE`` for an arm with its ground), for a perspective camera of
vertical field of view ``fov`` on a view about as wide as high, as the console's is.

Presets, all about the same focus: ``front`` (the default), ``side`` (a quarter turn round, low:
the heights, the peg's depth in its hole), ``top`` (from high above with a narrow field, nearly
a plan, leaning to the side away from the front camera: the arm at the top of the view) and
``follow`` (the tool, from the front's side, lower and closer; the page moves it with the tool).
No camera stands inside the arm or just behind one of its links (``ARM_MARGIN``).
Pure: numpy, the robot's forward kinematics and the cell's shapes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shared.cells.cell import Cell
from shared.robots.shapes import link_meshes

#: vertical field of view the views are fitted for: viser's default (three.js's), 75 deg
DEFAULT_FOV = np.radians(75.0)
#: the share of the view's narrower side the focus fills
FILL_TASK = 0.45  # a task's objects are small: the table, the gripper and the arm around them show too
FILL_SCENE = 0.7  # an arm with what it reaches: that is the whole picture
FRONT_ELEVATION = np.radians(40.0)
SIDE_ELEVATION = np.radians(20.0)
#: not 90: the page's orbit controls keep +z up and need a direction; leaning to the side away
#: from the front camera, over the work rather than over the arm behind it
TOP_ELEVATION = np.radians(85.0)
#: the top view looks from far with a narrow field, nearly a plan: an arm standing over the work
#: then covers no more than its own outline (close to, it would fill the view)
TOP_FOV = np.radians(20.0)
#: how far the follow view stands from the tool, as a share of the front view's distance
FOLLOW_SHARE = 0.55
#: where no task line gives a direction: the camera this far round from straight in front of the arm
QUARTER_TURN = np.radians(-45.0)
#: across a task line the camera turns at most this far from straight across, to keep the arm's
#: links at least ``ARM_CLEARANCE`` off its line of sight (the first turn, in ``TURN_STEP``s, that does)
MAX_TURN = np.radians(45.0)
TURN_STEP = np.radians(5.0)
ARM_CLEARANCE = np.radians(35.0)
MIN_DISTANCE = 0.25  # m: never closer than this to the focus's centre
#: m: the camera stands at least this far beyond the arm at home along its line of sight (never
#: inside a link, no link looming in front of the lens)
ARM_MARGIN = 0.2
FOLLOW_ELEVATION = np.radians(30.0)  # low enough to look under a forearm that comes down onto the tool
FEATURE_TOLERANCE = 0.002  # m: a fixture "carries" a feature lying this close to its box
REACH_SAMPLES = 600
PRESETS = ("front", "side", "top", "follow")


@dataclass(frozen=True)
class ViewPose:
    """A camera: where it stands, what it looks at, the world's up (+z), vertical field of view."""

    position: np.ndarray
    look_at: np.ndarray
    fov: float = DEFAULT_FOV
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    @property
    def forward(self) -> np.ndarray:
        f = self.look_at - self.position
        return f / np.linalg.norm(f)

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up on screen, forward), unit vectors in the world."""
        f = self.forward
        r = np.cross(f, self.up)
        if np.linalg.norm(r) < 1e-9:  # looking along up: any right will do
            r = np.cross(f, [1.0, 0.0, 0.0])
        r /= np.linalg.norm(r)
        return r, np.cross(r, f), f

    def project(self, points: np.ndarray, aspect: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Normalised view coordinates (n, 2) of world points, -1..1 across the view's width and
        height (x right, y up), and their depths along the view (m; positive: in front)."""
        r, u, f = self.basis()
        d = np.atleast_2d(np.asarray(points, dtype=float)) - self.position
        depth = d @ f
        t = np.tan(self.fov / 2.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = np.column_stack([(d @ r) / (depth * t * aspect), (d @ u) / (depth * t)])
        return xy, depth


@dataclass(frozen=True)
class WorkFocus:
    """What the view must hold: ``points`` (n, 3, world, m); ``task_points``: the task's main
    points (features, movable objects), whose line the view looks across; ``base``: the robot's
    base; ``tool``: the tool point at the home pose; ``names``: what ``points`` came from;
    ``arm``: points along the arm at home, the gripper's link left out (the camera keeps off them);
    ``fill``: the share of the view the points fill (``FILL_TASK`` or ``FILL_SCENE``)."""

    points: np.ndarray
    task_points: np.ndarray
    base: np.ndarray
    tool: np.ndarray
    names: tuple[str, ...]
    arm: np.ndarray
    fill: float = FILL_TASK

    @property
    def centre(self) -> np.ndarray:
        return (self.points.min(axis=0) + self.points.max(axis=0)) / 2.0


@dataclass(frozen=True)
class CellViews:
    """The cell's camera presets (``PRESETS`` but ``follow``, which moves) and the follow offset."""

    front: ViewPose
    side: ViewPose
    top: ViewPose
    follow_offset: np.ndarray
    """Camera position minus the tool point for the follow view (m, world)."""
    focus: WorkFocus

    def preset(self, name: str, tool: np.ndarray | None = None) -> ViewPose:
        """A preset by name; ``follow`` needs the tool point (world, m) it looks at."""
        if name == "follow":
            p = np.asarray(tool if tool is not None else self.focus.tool, dtype=float)
            return ViewPose(p + self.follow_offset, p.copy(), self.front.fov)
        if name not in ("front", "side", "top"):
            from shared.errors import UnknownNameError

            raise UnknownNameError("camera preset", name, PRESETS)
        return getattr(self, name)


# -- the focus --------------------------------------------------------------------------------
def _box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def _world_vertices(shapes, world_T: np.ndarray) -> np.ndarray | None:
    mesh = link_meshes(tuple(shapes))
    if mesh is None:
        return None
    v = np.asarray(mesh.vertices, dtype=float)
    return v @ world_T[:3, :3].T + world_T[:3, 3]


def _home_tool(cell: Cell) -> tuple[np.ndarray, np.ndarray]:
    """World positions of the tool point and of the last link's origin at the home pose."""
    base_T_tool = cell.robot.fk(np.asarray(cell.q_home, dtype=float), cell.robot.new_data())
    world_T_tool = cell.world_T_base @ base_T_tool
    return (world_T_tool @ cell.flange_T_tcp)[:3, 3], world_T_tool[:3, 3]


def _arm_points(cell: Cell) -> np.ndarray:
    """Corners of each link's box at the home pose (world)."""
    robot = cell.robot
    poses = cell.world_T_base @ robot.link_poses(np.asarray(cell.q_home, dtype=float), robot.new_data())
    out = [cell.world_T_base[:3, 3][None]]
    for i, world_T_link in enumerate(poses):
        v = _world_vertices(robot.shapes.get(i, ()), world_T_link)
        if v is not None:
            out.append(_box_corners(v.min(axis=0), v.max(axis=0)))
        else:
            out.append(world_T_link[:3, 3][None])
    return np.concatenate(out)


def _arm_line(cell: Cell) -> np.ndarray:
    """Link origins at home and the midpoints between them, up to the wrist (world)."""
    robot = cell.robot
    origins = (cell.world_T_base @ robot.link_poses(np.asarray(cell.q_home, dtype=float), robot.new_data()))[:, :3, 3]
    origins = origins[:-1]  # the last link carries the gripper: it stands over the work by design
    mids = (origins[1:] + origins[:-1]) / 2.0
    return np.concatenate([origins, mids])


def reach_points(cell: Cell, n: int = REACH_SAMPLES, seed: int = 0) -> np.ndarray:
    """Tool points (n, 3, world) of joint vectors drawn evenly over the joint ranges."""
    robot = cell.robot
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(robot.lower, dtype=float), np.asarray(robot.upper, dtype=float)
    lo, hi = np.maximum(lo, -np.pi * 2), np.minimum(hi, np.pi * 2)  # unlimited joints: one turn each way
    data = robot.new_data()
    out = np.empty((n, 3))
    for k, q in enumerate(rng.uniform(lo, hi, size=(n, robot.dof))):
        out[k] = (cell.world_T_base @ robot.fk(q, data) @ cell.flange_T_tcp)[:3, 3]
    return out


def work_focus(cell: Cell) -> WorkFocus:
    """The points the view must hold (see the module docstring)."""
    tool, flange = _home_tool(cell)
    features = {name: f.world_T_feature[:3, 3] for name, f in cell.features.items()}
    points: list[np.ndarray] = []
    names: list[str] = []
    task: list[np.ndarray] = list(features.values())
    boxes: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    vertices: dict[str, np.ndarray] = {}
    for obj in cell.objects:
        if obj.held:
            continue  # rides with the gripper, which the focus holds
        v = _world_vertices(obj.shapes, obj.world_T_object)
        if v is not None:
            boxes[obj.name] = (v.min(axis=0), v.max(axis=0))
            vertices[obj.name] = v
    for obj in cell.objects:
        if obj.name not in boxes:
            continue
        lo, hi = boxes[obj.name]
        carries = any(np.all(p >= lo - FEATURE_TOLERANCE) and np.all(p <= hi + FEATURE_TOLERANCE) for p in features.values())
        if obj.movable or carries:
            points.append(_box_corners(lo, hi))
            names.append(obj.name)
            if obj.movable:
                task.append((lo + hi) / 2.0)
    if features:
        points.append(np.array(list(features.values())))
        names += list(features)
    fill = FILL_TASK
    if points:  # a task: its objects, and the gripper over them
        points += [tool[None], flange[None]]
        names.append("tool")
    else:  # the arm, and what of the rest it can reach
        fill = FILL_SCENE
        points.append(_arm_points(cell))
        names.append("arm")
        reach = reach_points(cell)
        r_lo, r_hi = reach.min(axis=0), reach.max(axis=0)
        for name, (lo, hi) in boxes.items():
            c_lo, c_hi = np.maximum(lo, r_lo), np.minimum(hi, r_hi)
            if np.all(c_lo[:2] <= c_hi[:2]):
                v = vertices[name]
                inside = np.all((v[:, :2] >= c_lo[:2]) & (v[:, :2] <= c_hi[:2]), axis=1)
                # the object where the arm reaches over it: its own vertices there, else its box there
                points.append(v[inside] if inside.sum() >= 4 else _box_corners(np.r_[c_lo[:2], lo[2]], np.r_[c_hi[:2], hi[2]]))
                names.append(name)
    return WorkFocus(np.concatenate(points), np.array(task).reshape(-1, 3), cell.world_T_base[:3, 3].copy(), tool,
                     tuple(names), _arm_line(cell), fill)


# -- the views --------------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _rot_z(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], 0.0])


def task_axis(focus: WorkFocus) -> np.ndarray | None:
    """The horizontal line the task's main points lie along (unit, world), or ``None`` when
    they are fewer than two or lie within a centimetre of each other."""
    xy = focus.task_points[:, :2]
    if len(xy) < 2:
        return None
    centred = xy - xy.mean(axis=0)
    if np.max(np.linalg.norm(centred, axis=1)) < 0.01:
        return None
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    return np.array([axis[0], axis[1], 0.0])


def arm_clearance(focus: WorkFocus, direction: np.ndarray) -> float:
    """The smallest angle (rad) between ``direction`` (from the focus's centre toward the camera)
    and the arm's points on the camera's side of the centre (pi where there are none)."""
    rel = focus.arm - focus.centre
    rel = rel[rel @ direction > 0.0]
    if not len(rel):
        return float(np.pi)
    cos = (rel @ direction) / np.linalg.norm(rel, axis=1)
    return float(np.arccos(np.clip(cos.max(), -1.0, 1.0)))


def front_direction(focus: WorkFocus, elevation: float = FRONT_ELEVATION) -> np.ndarray:
    """Horizontal unit vector from the focus's centre toward the front camera.

    Across a task line: from the base's side (the operator stands behind the arm, as at its
    teach pendant: away from the robot is into the screen, and the drive handles, which reach
    from the tool along +x and +y, fall beyond the work rather than over it), turned from
    straight across by the smallest step that keeps the arm ``ARM_CLEARANCE`` off the line of
    sight (at most ``MAX_TURN``; failing that, the turn that keeps it furthest off). Without a
    task line: ``QUARTER_TURN`` round from straight in front of the arm."""
    away = focus.centre - focus.base
    away[2] = 0.0
    away = _unit(away) if np.linalg.norm(away) > 0.02 else np.array([1.0, 0.0, 0.0])
    axis = task_axis(focus)
    if axis is None:
        return _unit(_rot_z(away, QUARTER_TURN))
    across = np.array([-axis[1], axis[0], 0.0])
    if across @ away > 1e-6 or (abs(across @ away) <= 1e-6 and across[1] > 0):
        across = -across  # the base's side (at a tie, the -y side: the world's front)
    turns = sorted(np.arange(-MAX_TURN, MAX_TURN + 1e-9, TURN_STEP), key=lambda a: (round(abs(a), 9), a))
    best, best_clearance = across, -1.0
    for turn in turns:
        h = _unit(_rot_z(across, turn))
        clearance = arm_clearance(focus, _direction(h, elevation))
        if clearance >= ARM_CLEARANCE:
            return h
        if clearance > best_clearance + 1e-9:
            best, best_clearance = h, clearance
    return best


def beyond(arm: np.ndarray | None, look: np.ndarray, direction: np.ndarray, t: float, fov: float = DEFAULT_FOV) -> float:
    """The smallest distance from ``look`` along ``direction``, ``t`` or more, at which no point
    of the ``arm`` stands within ``ARM_MARGIN`` of the camera's plane near the line of sight (in
    view, or about to be): such a point is pushed ``ARM_MARGIN`` in front of the camera."""
    if arm is None or not len(arm):
        return t
    rel = arm - look
    along = rel @ direction
    lateral = np.sqrt(np.maximum(np.einsum("ij,ij->i", rel, rel) - along**2, 0.0))
    spread = np.tan(fov / 2.0) * np.sqrt(2.0)  # to the view's corners
    for _ in range(len(arm) + 1):
        depth = t - along
        near = (depth > -ARM_MARGIN) & (depth < ARM_MARGIN) & (lateral < ARM_MARGIN + np.maximum(depth, 0.0) * spread)
        if not near.any():
            break
        t = float(np.max(along[near])) + ARM_MARGIN
    return t


def _fit_at(points: np.ndarray, centre: np.ndarray, direction: np.ndarray, fov: float, fill: float, aspect: float,
            min_distance: float, arm: np.ndarray | None) -> ViewPose:
    """The camera on the ray ``centre + t * direction`` looking at ``centre``, at the smallest
    ``t`` that keeps every point inside ``fill`` of the view and the camera beyond the arm."""
    r, u, _ = ViewPose(centre + direction, centre.copy(), fov).basis()
    rel = points - centre
    kx, ky = fill * np.tan(fov / 2.0) * aspect, fill * np.tan(fov / 2.0)
    # a point at rel projects inside when |rel.r| <= kx (t - rel.v), |rel.u| <= ky (t - rel.v)
    need = np.maximum(np.abs(rel @ r) / kx, np.abs(rel @ u) / ky) + rel @ direction
    t = beyond(arm, centre, direction, max(float(need.max()), min_distance), fov)
    return ViewPose(centre + t * direction, centre.copy(), fov)


def fit(focus_points: np.ndarray, centre: np.ndarray, direction: np.ndarray, fov: float = DEFAULT_FOV,
        fill: float = FILL_TASK, aspect: float = 1.0, min_distance: float = MIN_DISTANCE,
        arm: np.ndarray | None = None) -> ViewPose:
    """A camera looking along ``-direction`` (unit, from the work toward the camera) that holds
    every point inside ``fill`` of the view, as close as that allows but ``ARM_MARGIN`` beyond
    the ``arm``'s points: first at ``centre``, then at the middle of what it sees (a few rounds),
    so the points sit centred in the view."""
    points = np.asarray(focus_points, dtype=float)
    look = np.asarray(centre, dtype=float).copy()
    view = _fit_at(points, look, direction, fov, fill, aspect, min_distance, arm)
    for _ in range(4):
        xy, _ = view.project(points, aspect)
        mid = (xy.min(axis=0) + xy.max(axis=0)) / 2.0
        if np.max(np.abs(mid)) < 1e-3:
            break
        r, u, _ = view.basis()
        t = np.tan(fov / 2.0) * float(np.linalg.norm(view.position - view.look_at))
        look = look + mid[0] * t * aspect * r + mid[1] * t * u
        view = _fit_at(points, look, direction, fov, fill, aspect, min_distance, arm)
    return view


def _direction(horizontal: np.ndarray, elevation: float) -> np.ndarray:
    return _unit(np.cos(elevation) * horizontal + np.array([0.0, 0.0, np.sin(elevation)]))


def cell_views(cell: Cell, fov: float = DEFAULT_FOV, focus: WorkFocus | None = None) -> CellViews:
    """The default view (``front``) and the presets of ``cell`` (see the module docstring)."""
    focus = focus or work_focus(cell)
    centre = focus.centre
    d = front_direction(focus)
    front = fit(focus.points, centre, _direction(d, FRONT_ELEVATION), fov, focus.fill, arm=focus.arm)
    side = fit(focus.points, centre, _direction(_rot_z(d, -np.pi / 2.0), SIDE_ELEVATION), fov, focus.fill, arm=focus.arm)
    top = fit(focus.points, centre, _direction(-d, TOP_ELEVATION), min(TOP_FOV, fov), focus.fill, arm=focus.arm)
    distance = float(np.linalg.norm(front.position - front.look_at))
    toward = _direction(d, FOLLOW_ELEVATION)
    follow = toward * beyond(focus.arm, focus.tool, toward, max(FOLLOW_SHARE * distance, MIN_DISTANCE), fov)
    return CellViews(front, side, top, follow, focus)
