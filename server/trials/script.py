"""The approach trial's scripted operator: the motion from the cell's home pose to above the peg,
as the statements the console would generate from it, one per stroke of about ``statement_s``.

The operator's motion is a straight path from the tool point at home to ``clearance`` above the
peg's top (thesis §4.6: "from the initial position to near the peg"), cut into ``n`` equal strokes
with the gripper's orientation kept. Each stroke is a ``DRAW TO ... IN WORK WITH SPEED v mm/s``
whose speed is solved with the telerobot's own planner so its planned duration is
``statement_s``: the virtual robot's time is the sum of these planned durations.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from shared.errors import InputError

APPROACH_OBJECT = "peg"
DEFAULT_CLEARANCE_M = 0.070  # 70 mm above the peg's top, where the shipped peg transfer's approach ends
RETURN_SPEED_MM_S = 60.0


@dataclass(frozen=True)
class ScriptedStatement:
    text: str
    planned_s: float  # planned duration from the telerobot's planner, s


@dataclass(frozen=True)
class ApproachScript:
    """The operator's approach: the statements in order, and the statement that takes the arm
    back to where the approach starts (run between modes, not timed)."""

    cell: str
    start_work_mm: tuple[float, float, float]
    target_work_mm: tuple[float, float, float]
    statements: tuple[ScriptedStatement, ...]
    back_to_start: str

    @property
    def virtual_s(self) -> float:
        return sum(s.planned_s for s in self.statements)


def _fmt(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.2f}" for v in np.round(p * 1e3, 2) + 0.0) + ") mm"


def _top_height(obj) -> float:
    """Height of an object's top above its origin (m), from its box shapes; 0 without any."""
    tops = [float(s.link_T_shape[2, 3] + s.size[2] / 2.0) for s in obj.shapes if s.kind == "box"]
    return max(tops, default=0.0)


def approach_script(cell_path: str | Path, n: int = 4, statement_s: float = 1.0,
                    clearance_m: float = DEFAULT_CLEARANCE_M) -> ApproachScript:
    """The approach from the cell's home pose to ``clearance_m`` above the peg in ``n`` strokes."""
    from shared.cells.loader import load_cell
    from shared.language.parser import parse_statement
    from shared.motion import plan_program

    cell = load_cell(cell_path)
    if APPROACH_OBJECT not in cell.object_names:
        raise InputError(f"{cell_path}: the cell has no object named {APPROACH_OBJECT!r} to approach")
    if "work" not in cell.frames:
        raise InputError(f"{cell_path}: the cell has no 'work' frame to state the approach in")
    robot = cell.robot
    work_inv = np.linalg.inv(cell.frames["work"])
    start = (work_inv @ cell.world_T_base @ robot.fk(cell.q_home) @ cell.flange_T_tcp)[:3, 3]
    peg = cell.object(APPROACH_OBJECT)
    target = (work_inv @ peg.world_T_object)[:3, 3] + np.array([0.0, 0.0, _top_height(peg) + clearance_m])

    statements: list[ScriptedStatement] = []
    q = cell.q_home
    for i in range(1, n + 1):
        p = start + (target - start) * i / n
        text, planned, q = _stroke(p, q, statement_s, robot, cell, parse_statement, plan_program)
        statements.append(ScriptedStatement(text, planned))
    back = f"DRAW TO {_fmt(start)} IN WORK WITH SPEED {RETURN_SPEED_MM_S:g} mm/s"
    as_mm = lambda v: tuple(round(float(x) * 1e3, 2) for x in v)  # noqa: E731
    return ApproachScript(str(cell_path), as_mm(start), as_mm(target), tuple(statements), back)


def _stroke(p, q, statement_s, robot, cell, parse_statement, plan_program):
    """The DRAW to ``p`` from joints ``q`` whose planned duration is ``statement_s`` (secant on
    the speed; the planner's duration falls monotonically with it)."""

    def plan(speed: float):
        text = f"DRAW TO {_fmt(p)} IN WORK WITH SPEED {speed:.3f} mm/s"
        result = plan_program([parse_statement(text)], robot, cell, start_q=q)
        if result.refusal is not None:
            raise InputError(f"the approach cannot be planned in {cell.name}: {result.refusal}")
        return text, float(result.segments[0].duration), result.q_final

    length_mm = float(np.linalg.norm(p * 1e3 - _tool_work(robot, cell, q) * 1e3))
    speed = max(length_mm / statement_s, 0.5)
    for _ in range(6):
        text, planned, q_end = plan(speed)
        if abs(planned - statement_s) < 0.005:
            break
        speed *= planned / statement_s
    return text, planned, q_end


def _tool_work(robot, cell, q) -> np.ndarray:
    return (np.linalg.inv(cell.frames["work"]) @ cell.world_T_base @ robot.fk(q) @ cell.flange_T_tcp)[:3, 3]
