"""``teleprog plan``: plan a program with the telerobot's own planner and print the summary.

FILE is the text form (``.tp``) or the JSON form (``.json``), read by
``shared.language.parser.parse_file``; every parse error is printed on its own line. The summary gives each statement's duration (s) and the final joint vector (deg), so a program
can be checked for reachability and timing from the command line. A program that cannot be
planned prints what was planned and the refusal, and exits 1.
"""

from __future__ import annotations

import argparse
import math
import sys

from server.cli import print_json
from shared.errors import InputError

_TASK_END_TEXT = {
    "still": "the arm stays where it is",
    "retract": "the arm ends retracted along the hole",
    "unknown": "the arm's pose is known when the robot reports it",
}


def _cmd_plan(args: argparse.Namespace) -> int:
    import numpy as np

    from shared.cells.loader import load_cell
    from shared.language.parser import parse_file
    from shared.motion import plan_program
    from shared.robots.loader import load_robot

    robot = load_robot(args.robot)
    cell = load_cell(args.cell) if args.cell else None
    if cell is not None and cell.robot.name != robot.name:
        raise InputError(f"cell {cell.name!r} holds robot {cell.robot.name!r}, not {robot.name!r}")
    start = None
    if args.start is not None:
        start = robot.as_q(np.radians(args.start))
        robot.check_limits(start)
    parsed = parse_file(args.file)
    if not parsed.ok:
        for line in parsed.error_lines():
            print(f"teleprog: error: {line}", file=sys.stderr)
        return 1
    program = parsed.statements
    zones = None
    if not args.no_zones:
        from shared.collision.interference import robot_zones

        zones = robot_zones(robot, pairs=((2, 3),) if robot.dof >= 3 else ())
    plan = plan_program(program, robot, cell, start, zones=zones)
    rows = [
        {
            "index": seg.index + 1,
            "kind": seg.statement.kind,
            "duration": None if seg.statement.kind == "TASK" else round(seg.duration, 6),
            "warnings": list(seg.warnings),
            **({"task_end": seg.arm_end} if seg.arm_end is not None else {}),
        }
        for seg in plan.segments
    ]
    refusal = None
    if plan.refusal is not None:
        r = plan.refusal
        refusal = {
            "index": (r.index or 0) + 1,
            "kind": program[r.index].kind if r.index is not None else None,
            "reason": r.reason.value,
            "message": str(r),
        }
    final_deg = [round(math.degrees(v), 6) for v in plan.q_final]
    if args.json:
        print_json(
            {
                "ok": plan.ok,
                "robot": robot.name,
                "cell": cell.name if cell is not None else None,
                "statements": rows,
                "duration_unit": "s",
                "total_duration": round(plan.duration, 6),
                "final_q": final_deg,
                "unit": "deg",
                "final_q_before_task": plan.after_task,
                "refusal": refusal,
            }
        )
    else:
        for row in rows:
            dur = f"task, run by the robot ({_TASK_END_TEXT[row['task_end']]})" if row["duration"] is None else f"{row['duration']:.3f} s"
            print(f"{row['index']:5d}  {row['kind']:<7} {dur}")
        print(f"total {plan.duration:.3f} s over {len(rows)} statement(s)")
        print("final joints: " + "  ".join(f"{v:9.3f}" for v in final_deg) + "  deg")
        if plan.after_task is not None:
            print(f"  (where TASK {plan.after_task} is predicted to end, within the tolerance its effect declares; "
                  "the robot reports where it really ends)")
    if plan.refusal is not None:
        print(f"teleprog: error: {plan.refusal}", file=sys.stderr)
        return 1
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plan", help="plan a program: duration of each statement, final joint vector")
    p.add_argument("file", help="program file: text form (.tp) or JSON form (.json)")
    p.add_argument("--robot", required=True, help="puma562, rover, or a .urdf/.toml file")
    p.add_argument("--cell", help="cell file (.toml); gives the frames, tool point and home pose")
    p.add_argument("--start", type=float, nargs="+", metavar="Q", help="start joint vector in degrees (default: cell home, else zero)")
    p.add_argument("--no-zones", action="store_true", help="do not route MOVE/DRIVE round the arm's interference zones (seed 001)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(handler=_cmd_plan)

