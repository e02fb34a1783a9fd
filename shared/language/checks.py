"""Checks of a parsed program against a robot and (optionally) its cell.

The checks follow the program as the robot would, tracking the joint vector from a start
vector (default: the cell's home, else zeros): a Cartesian target in ``TOOL`` is relative to the
tool pose where its statement starts, so a reachability verdict depends on everything before it.
After a target fails, the robot is taken to stay where it was (what the telerobot does when a
statement fails), so later problems are still reported.

Rules, each reported as a :class:`Problem` with the statement's index, its source line and
column (text form) or JSON pointer (JSON form), and the field at fault where there is one:

* ``values``: every number is finite (the models refuse NaN, infinity and values beyond the
  physical bounds of ``shared.language.bounds``; this catches statements built around them);
* ``joints``: a MOVE has one value per joint; a DRIVE names an existing joint;
* ``limits``: MOVE and DRIVE targets lie within the joint ranges;
* ``reach``: a DRAW/ROTATE/MOVES target has an inverse-kinematics solution within the ranges
  (targets only; the straight line between them is the planner's business); a position-only arm
  (the rover) cannot take an orientation;
* ``frame``: WORK needs a cell; TOOL needs a known start pose;
* ``units``: a WITH SPEED fits its action (joint moves: % or deg/s; DRAW: % or mm/s; ROTATE:
  % or deg/s; MOVES: any of the three); percent at most 100 (also for SPEED statements);
* ``names``: a TASK names a known task (``shared.language.tasks``) with the right number and
  kind of arguments, and the objects and features exist in the cell; the gripper must hold
  what ``release``/``extract_peg``/``insert_peg`` need and be empty for ``grasp``;
* ``program``: what may follow a task call (``shared.language.task_rule``, the rule the editor
  and the planner apply too): after a task whose end pose is unknown (``insert_peg``) nothing
  that moves the arm may follow. Tasks that keep the arm still (grasp, release) or end at a
  pose their contract fixes (extract_peg) may be followed; ``strict_tasks=True`` applies §4.3.6
  literally: nothing follows any task.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from shared.cells.cell import Cell
from shared.errors import InputError, TeleprogError
from shared.language.statements import (
    ALLOWED_SPEED_UNITS,
    SPEED_UNIT_TEXT,
    Draw,
    Drive,
    Frame,
    Move,
    Moves,
    Rotate,
    SetSpeed,
    Speed,
    SpeedUnit,
    Statement,
    TaskCall,
    is_action,
)
from shared.language.task_rule import UnknownPose, may_follow, pose_after, why_not
from shared.language.tasks import EXTRACT_LIFT_M, TASKS, ArgKind, TaskSpec, resolve_name
from shared.robots.ik import ik_target, positions_tool_only
from shared.robots.ik_kernels import solve_ik_nearest
from shared.robots.model import LIMIT_TOLERANCE, Robot
from shared.spatial import invert, rpy_to_matrix

log = logging.getLogger(__name__)

RULES = ("values", "joints", "limits", "reach", "frame", "units", "names", "program")


@dataclass(frozen=True)
class Problem:
    """One finding: ``index`` is the 0-based statement index, ``line``/``col`` its source
    position in the text form, ``pointer`` the statement's JSON pointer in the JSON form (``/3``;
    by default its index in the program list), ``field`` the statement's field at fault
    (``target``, ``joints/2``), if any."""

    index: int
    line: int | None
    rule: str
    message: str
    col: int | None = None
    pointer: str | None = None
    field: str | None = None

    @property
    def json_pointer(self) -> str:
        """The fault's place in the JSON form: ``/3/target``."""
        base = self.pointer if self.pointer is not None else f"/{self.index}"
        return f"{base}/{self.field}" if self.field else base

    def format(self, path: str) -> str:
        """``file:line:col: message`` for the text form, ``file: /3/target: message`` otherwise."""
        if self.line is not None:
            where = f"{path}:{self.line}:{self.col if self.col is not None else 1}"
        else:
            where = f"{path}: {self.json_pointer}"
        return f"{where}: {self.message}"


@dataclass(frozen=True)
class CheckResult:
    """Every problem found, and the tracked joint vector after each statement (``None`` where
    the checks cannot know it, e.g. after ``insert_peg``)."""

    problems: list[Problem]
    q_after: list[np.ndarray | None] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems


def _deg(v: float) -> str:
    return f"{float(v) * (180.0 / math.pi):.3f}"  # plain floats: no numpy overflow warning


def _mm3(p: Sequence[float]) -> str:
    return "(" + ", ".join(f"{x * 1e3:.3f}" for x in p) + ") mm"


def _speed_text(s: Speed) -> str:
    scale = {SpeedUnit.FRACTION: 100.0, SpeedUnit.M_PER_S: 1e3, SpeedUnit.RAD_PER_S: 180.0 / math.pi}[s.unit]
    return f"{s.value * scale:g} {SPEED_UNIT_TEXT[s.unit]}"


_FLOAT_FIELDS: dict[str, tuple[str, ...]] = {
    "MOVE": ("joints",), "DRIVE": ("target",), "DRAW": ("position",), "ROTATE": ("rpy",), "MOVES": ("position", "rpy"),
}


def _finite(values: object) -> bool:
    if isinstance(values, (tuple, list)):
        return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)
    return isinstance(values, (int, float)) and math.isfinite(values)


def _non_finite(st: Statement) -> str:
    """The name of the first numeric field of ``st`` that is NaN or infinite ('' if none). The
    models refuse such values; a statement made with ``model_construct`` skips them. Only the
    fields each kind has are read (a missing attribute of a pydantic model is slow to miss)."""
    for name in _FLOAT_FIELDS.get(st.kind, ()):
        if not _finite(getattr(st, name)):
            return name
    if st.kind == "SPEED" and not _finite(st.speed.value):
        return "speed/value"
    if st.kind in _FLOAT_FIELDS:
        if st.speed is not None and not _finite(st.speed.value):
            return "speed/value"
        until = st.until
        if until is not None and until.kind != "contact" and not _finite(getattr(until, "newtons", getattr(until, "seconds", 0.0))):
            return "until/newtons" if until.kind == "force" else "until/seconds"
    return ""


class _Checker:
    def __init__(
        self, robot: Robot, cell: Cell | None, q_start: np.ndarray, lines: Sequence[int | None], strict_tasks: bool,
        cols: Sequence[int | None] = (), pointers: Sequence[str | None] = (),
    ) -> None:
        self.robot = robot
        self.cell = cell
        self.lines = lines
        self.cols = cols
        self.pointers = pointers
        self.problems: list[Problem] = []
        self.q: np.ndarray | None = q_start
        self.world_T_base = cell.world_T_base if cell is not None else np.eye(4)
        self.flange_T_tcp = cell.flange_T_tcp if cell is not None else np.eye(4)
        self.position_only = positions_tool_only(robot)
        self.holding: str | None = None
        if cell is not None:
            held = [o.name for o in cell.objects if o.held]
            self.holding = held[0] if held else None
        self.unknown_after: UnknownPose | None = None  # task that left the arm pose unknown
        self.strict_tasks = strict_tasks
        self.strict_after: tuple[str, int] | None = None  # any task, when strict_tasks

    # -- helpers --------------------------------------------------------------------------
    def add(self, index: int, rule: str, message: str, field: str | None = None) -> None:
        line = self.lines[index] if index < len(self.lines) else None
        col = self.cols[index] if index < len(self.cols) else None
        ptr = self.pointers[index] if index < len(self.pointers) else None
        self.problems.append(Problem(index, line, rule, message, col, ptr, field))

    def where(self, index: int) -> str:
        line = self.lines[index] if index < len(self.lines) else None
        return f"line {line}" if line is not None else f"statement {index + 1}"

    def limits(self, index: int, q: np.ndarray, what: str, field: str | None = None) -> bool:
        """Each joint within its range; ``field``: the statement's field to name (``target``),
        else ``joints/<j>`` for the joint at fault."""
        ok = True
        r = self.robot
        for j in range(r.dof):
            if not (r.lower[j] - LIMIT_TOLERANCE <= q[j] <= r.upper[j] + LIMIT_TOLERANCE):
                self.add(
                    index, "limits",
                    f"{what}: joint {j + 1} at {_deg(q[j])} deg is outside its range "
                    f"[{_deg(r.lower[j])}, {_deg(r.upper[j])}] deg",
                    field or f"joints/{j}",
                )
                ok = False
        return ok

    def world_T_tcp(self, q: np.ndarray) -> np.ndarray:
        return self.world_T_base @ self.robot.fk(q) @ self.flange_T_tcp

    def check_speed(self, index: int, st: Statement) -> None:
        """A WITH SPEED must fit the action. A SPEED statement in effect is not checked against
        each action: the planner applies a mm/s SPEED as a tool-point cap on joint moves, and a
        deg/s one as a rotation cap on Cartesian moves, which is meaningful for every kind."""
        own = getattr(st, "speed", None)
        if own is None:
            return
        allowed = ALLOWED_SPEED_UNITS[st.kind]
        if own.unit not in allowed:
            self.add(
                index, "units",
                f"{st.kind} cannot take WITH SPEED {_speed_text(own)}: it takes "
                + " or ".join(SPEED_UNIT_TEXT[u] for u in allowed),
                "speed/unit",
            )
        elif own.unit is SpeedUnit.FRACTION and own.value > 1.0:
            self.add(index, "units", f"{st.kind} WITH SPEED {_speed_text(own)} is above 100 %", "speed/value")

    # -- statements -----------------------------------------------------------------------
    def run(self, statements: Sequence[Statement]) -> list[np.ndarray | None]:
        q_after: list[np.ndarray | None] = []
        for index, st in enumerate(statements):
            if self.strict_after is not None:
                name, at = self.strict_after
                self.add(index, "program", f"{st.kind} cannot follow TASK {name} ({self.where(at)}): nothing may follow a task call")
                q_after.append(None)
                continue
            if self.unknown_after is not None and not may_follow(st, self.unknown_after):
                self.add(index, "program", why_not(st, self.unknown_after, self.where(self.unknown_after.index)))
                q_after.append(None)
                continue
            bad = _non_finite(st)
            if bad:
                self.add(index, "values", f"{st.kind}: {bad} is not a finite number", bad)
                q_after.append(None if self.q is None else self.q.copy())
                continue
            if is_action(st):
                self.check_speed(index, st)
            if isinstance(st, Move):
                self.move(index, st)
            elif isinstance(st, Drive):
                self.drive(index, st)
            elif isinstance(st, (Draw, Rotate, Moves)):
                self.cartesian(index, st)
            elif isinstance(st, SetSpeed):
                if st.speed.unit is SpeedUnit.FRACTION and st.speed.value > 1.0:
                    self.add(index, "units", f"SPEED {_speed_text(st.speed)} is above 100 %", "speed/value")
            elif isinstance(st, TaskCall):
                self.task(index, st)
                if self.strict_tasks:
                    self.strict_after = (st.name, index)
            q_after.append(None if self.q is None else self.q.copy())
        return q_after

    def move(self, index: int, st: Move) -> None:
        if len(st.joints) != self.robot.dof:
            self.add(index, "joints", f"MOVE gives {len(st.joints)} joint values; robot {self.robot.name!r} has {self.robot.dof} joints", "joints")
            return
        q = np.array(st.joints, dtype=float)
        if self.limits(index, q, "MOVE"):
            self.q = q

    def drive(self, index: int, st: Drive) -> None:
        if not 1 <= st.joint <= self.robot.dof:
            self.add(index, "joints", f"DRIVE J{st.joint}: robot {self.robot.name!r} has joints J1 to J{self.robot.dof}", "joint")
            return
        if self.q is None:
            return
        q = self.q.copy()
        q[st.joint - 1] = st.target
        if self.limits(index, q, f"DRIVE J{st.joint}", "target"):
            self.q = q

    def frame_T(self, index: int, frame: Frame, now: np.ndarray) -> np.ndarray | None:
        if frame is Frame.WORLD:
            return np.eye(4)
        if frame is Frame.BASE:
            return self.world_T_base
        if frame is Frame.TOOL:
            return now
        if self.cell is None:
            self.add(index, "frame", "frame WORK needs a cell (give --cell)", "frame")
            return None
        return self.cell.frame("work")

    def cartesian(self, index: int, st: Draw | Rotate | Moves) -> None:
        if self.position_only and not isinstance(st, Draw):
            self.add(
                index, "reach",
                f"{st.kind} sets the tool orientation, but robot {self.robot.name!r} positions its tool point only; use DRAW",
                "rpy",
            )
            return
        if self.q is None:
            return
        now = self.world_T_tcp(self.q)
        world_T_frame = self.frame_T(index, st.frame, now)
        if world_T_frame is None:
            return
        target = now.copy()
        if isinstance(st, (Draw, Moves)):
            target[:3, 3] = world_T_frame[:3, :3] @ np.asarray(st.position) + world_T_frame[:3, 3]
        if isinstance(st, (Rotate, Moves)):
            target[:3, :3] = world_T_frame[:3, :3] @ rpy_to_matrix(np.asarray(st.rpy))
        q = self.solve(target)
        if q is None:
            what = _mm3(st.position) if isinstance(st, (Draw, Moves)) else ""
            if isinstance(st, (Rotate, Moves)):
                what += (" " if what else "") + "(" + ", ".join(_deg(a) for a in st.rpy) + ") deg"
            outside = self.solve(target, respect_limits=False) is not None
            reason = "only outside the joint ranges" if outside else "outside the workspace"
            self.add(
                index, "reach", f"{st.kind} target {what} in {st.frame.value} is unreachable for {self.robot.name!r}: {reason}",
                "rpy" if isinstance(st, Rotate) else "position",
            )
            return
        self.q = q

    def solve(self, world_T_tcp: np.ndarray, respect_limits: bool = True) -> np.ndarray | None:
        """The IK solution nearest the running joint vector (what the planner picks), or None."""
        base_T_tool = invert(self.world_T_base) @ world_T_tcp @ invert(self.flange_T_tcp)
        try:
            return solve_ik_nearest(self.robot, q_seed=self.q, respect_limits=respect_limits, **ik_target(self.robot, base_T_tool))
        except TeleprogError as exc:  # a solver that cannot take this target at all
            log.debug("IK refused a target: %s", exc)
            return None

    def task(self, index: int, st: TaskCall) -> None:
        spec = TASKS.get(st.name) or TASKS.get(st.name.lower())
        if spec is None:
            known = ", ".join(t.signature() for t in TASKS.values())
            self.add(index, "names", f"unknown task {st.name!r}; known tasks: {known}", "name")
            self.q = None
            self.unknown_after = pose_after(st, index, self.unknown_after)
            return
        if len(st.args) != len(spec.params):
            self.add(index, "names", f"TASK {spec.name} takes {len(spec.params)} argument(s): {spec.signature()}; got {len(st.args)}", "args")
        args = [self.resolve(index, spec, kind, name) for kind, name in zip(spec.params, st.args)]
        self.gripper(index, spec, args)
        if spec.arm_end == "unknown":
            self.q = None
            self.unknown_after = pose_after(st, index, self.unknown_after)
        elif spec.arm_end == "retract" and self.q is not None:
            self.retract(index, st, spec, args)

    def resolve(self, index: int, spec: TaskSpec, kind: ArgKind, name: str) -> str | None:
        if self.cell is None:
            self.add(index, "names", f"TASK {spec.name}: {name!r} can only be checked against a cell (give --cell)")
            return None
        if kind is ArgKind.HOLE_FEATURE:
            found = resolve_name(name, tuple(self.cell.features))
            if found is None:
                self.add(index, "names", f"TASK {spec.name}: no feature {name!r} in cell {self.cell.name!r}; features: {', '.join(self.cell.features) or '(none)'}")
            elif self.cell.features[found].kind != "hole":
                self.add(index, "names", f"TASK {spec.name}: feature {found!r} is a {self.cell.features[found].kind}, not a hole")
            return found
        found = resolve_name(name, self.cell.object_names)
        if found is None:
            self.add(index, "names", f"TASK {spec.name}: no object {name!r} in cell {self.cell.name!r}; objects: {', '.join(self.cell.object_names)}")
        elif kind is ArgKind.PEG_OBJECT and not self.cell.object(found).movable:
            self.add(index, "names", f"TASK {spec.name}: object {found!r} is fixed; it needs a movable object")
        return found

    def gripper(self, index: int, spec: TaskSpec, args: list[str | None]) -> None:
        if spec.needs_holding is False:
            if self.holding is not None:
                self.add(index, "names", f"TASK {spec.name}: the gripper already holds {self.holding!r}")
            if args and args[0] is not None:
                self.holding = args[0]
        elif spec.needs_holding:
            if self.holding is None:
                self.add(index, "names", f"TASK {spec.name}: the gripper holds nothing")
            elif args and args[0] is not None and args[0] != self.holding:
                self.add(index, "names", f"TASK {spec.name}: the gripper holds {self.holding!r}, not {args[0]!r}")
            if spec.name == "release":
                self.holding = None

    def retract(self, index: int, st: TaskCall, spec: TaskSpec, args: list[str | None]) -> None:
        hole = args[1] if len(args) > 1 else None
        if hole is None or self.cell is None or self.q is None:
            self.q = None
            self.unknown_after = pose_after(st, index, self.unknown_after, "unknown")
            return
        axis = self.cell.features[hole].world_T_feature[:3, 2]
        target = self.world_T_tcp(self.q)
        target[:3, 3] += EXTRACT_LIFT_M * axis
        q = self.solve(target)
        if q is None:
            self.add(index, "reach", f"TASK {spec.name}: the pose {EXTRACT_LIFT_M * 1e3:g} mm up the axis of {hole} is unreachable")
            self.q = None
            self.unknown_after = pose_after(st, index, self.unknown_after, "unknown")
            return
        self.q = q


def start_vector(robot: Robot, cell: Cell | None, q_start: Sequence[float] | np.ndarray | None) -> np.ndarray:
    """The joint vector checks start from: given, else the cell's home, else zeros (clipped into
    the ranges). Raises ``InputError`` for a wrong length or a vector outside the ranges."""
    if q_start is not None:
        q = robot.as_q(q_start)
        if not robot.within_limits(q):
            robot.check_limits(q)
        return q
    if cell is not None:
        return np.array(cell.q_home, dtype=float)
    return np.clip(np.zeros(robot.dof), robot.lower, robot.upper)


def check_program(
    statements: Sequence[Statement],
    robot: Robot,
    cell: Cell | None = None,
    q_start: Sequence[float] | np.ndarray | None = None,
    lines: Sequence[int | None] | None = None,
    strict_tasks: bool = False,
    cols: Sequence[int | None] | None = None,
    pointers: Sequence[str | None] | None = None,
) -> CheckResult:
    """Check ``statements`` for ``robot`` (placed and tooled by ``cell`` when given), starting
    from ``q_start`` (radians). ``lines`` and ``cols`` give each statement's source position for
    the messages (text form), ``pointers`` its JSON pointer (JSON form; default ``/<index>``).
    ``strict_tasks``: the literal rule of §4.3.6, nothing at all may follow any task call
    (default: only what moves the arm may not follow a task whose end pose is unknown)."""
    if cell is not None and cell.robot.name != robot.name:
        raise InputError(f"cell {cell.name!r} is for robot {cell.robot.name!r}, not {robot.name!r}")
    q0 = start_vector(robot, cell, q_start)
    checker = _Checker(
        robot, cell, q0, list(lines) if lines is not None else [None] * len(statements), strict_tasks,
        list(cols or ()), list(pointers or ()),
    )
    q_after = checker.run(statements)
    return CheckResult(checker.problems, q_after)
