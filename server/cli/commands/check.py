"""``teleprog check``: check a program against a robot and cell; one line per problem."""

from __future__ import annotations

import argparse

from server.cli import print_json
from shared.errors import InputError


def _cmd_check(args: argparse.Namespace) -> int:
    import numpy as np

    from shared.language.checks import check_program
    from shared.language.parser import parse_file
    from shared.robots.loader import load_robot

    robot = load_robot(args.robot)
    cell = None
    if args.cell is not None:
        from shared.cells.loader import load_cell

        cell = load_cell(args.cell)
        if cell.robot.name != robot.name:
            raise InputError(f"cell {args.cell} holds robot {cell.robot.name!r}, not {robot.name!r}")
        robot = cell.robot
    q_start = None
    if args.start is not None:
        if len(args.start) != robot.dof:
            raise InputError(f"--start needs {robot.dof} joint angles (deg) for {robot.name!r}, got {len(args.start)}")
        q_start = np.radians(args.start)
    parsed = parse_file(args.file)
    result = check_program(
        parsed.statements, robot, cell, q_start=q_start, lines=parsed.lines, strict_tasks=args.strict_tasks,
        cols=parsed.cols, pointers=parsed.pointers,
    )
    # one list in file order (file:line:col, or file: /json/pointer): parse errors and check
    # problems interleaved by line and column, or by statement for the JSON form
    found = [((e.line or 0, e.col or 0, e.statement or 0), e.format(parsed.path)) for e in parsed.errors]
    found += [((p.line or 0, p.col or 0, _document_index(p.json_pointer)), p.format(parsed.path)) for p in result.problems]
    lines = [text for _, text in sorted(found, key=lambda item: item[0])]
    ok = parsed.ok and result.ok
    if args.json:
        final = next((q for q in reversed(result.q_after) if q is not None), None) if result.q_after else None
        print_json(
            {
                "ok": ok,
                "statements": len(parsed.statements),
                "parse_errors": [
                    {"line": e.line, "col": e.col, "pointer": e.pointer, "statement": e.statement, "message": e.message}
                    for e in parsed.errors
                ],
                "problems": [
                    {"line": p.line, "col": p.col, "pointer": None if p.line is not None else p.json_pointer,
                     "statement": p.index, "rule": p.rule, "message": p.message}
                    for p in result.problems
                ],
                "final_joints": None if final is None else np.degrees(final).tolist(),
                "unit": "deg",
            }
        )
    else:
        for line in lines:
            print(line)
        if ok:
            print(f"{parsed.path}: ok, {len(parsed.statements)} statements")
    return 0 if ok else 1


def _document_index(json_pointer: str) -> int:
    head = json_pointer.split("/")[1] if json_pointer.count("/") else ""
    return int(head) if head.isdigit() else 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("check", help="check a program against a robot and cell")
    p.add_argument("file", help="program file: text form (.tp) or JSON form (.json)")
    p.add_argument("--robot", required=True, help="puma562, rover, or a .urdf/.toml file")
    p.add_argument("--cell", help="cell file (.toml): placement, tool point, frames, objects, features")
    p.add_argument("--start", type=float, nargs="+", metavar="Q", help="start joint vector in degrees (default: the cell's home)")
    p.add_argument(
        "--strict-tasks", action="store_true",
        help="nothing at all may follow a task call (default: only arm motion after a task whose end pose is unknown)",
    )
    p.add_argument("--json", action="store_true")
    p.set_defaults(handler=_cmd_check)
