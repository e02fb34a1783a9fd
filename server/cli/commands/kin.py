"""``teleprog kin``: forward and inverse kinematics of any robot the loader knows."""

from __future__ import annotations

import argparse

import numpy as np

from server.cli import print_json
from shared.errors import TeleprogError


def _cmd_kin_fk(args: argparse.Namespace) -> int:
    from shared.robots.loader import load_robot

    robot = load_robot(args.robot)
    q = robot.as_q(np.radians(args.deg))
    if not args.ignore_limits:
        robot.check_limits(q)
    base_T_tool = robot.fk(q)
    if args.json:
        print_json({"position": base_T_tool[:3, 3].tolist(), "rotation": base_T_tool[:3, :3].tolist(), "unit": "m"})
    else:
        x, y, z = base_T_tool[:3, 3] * 1e3
        print(f"{robot.name} tool in base frame: x={x:.3f} mm y={y:.3f} mm z={z:.3f} mm")
        for row in base_T_tool[:3, :3]:
            print("  [" + "  ".join(f"{v: .6f}" for v in row) + "]")
    return 0


def _cmd_kin_ik(args: argparse.Namespace) -> int:
    from shared.robots.ik import distinct_branches, positions_tool_only, solve_ik
    from shared.robots.loader import load_robot
    from shared.spatial import pose_to_transform

    robot = load_robot(args.robot)
    scale = 1e-3 if args.unit == "mm" else 1.0
    xyz = np.array(args.xyz) * scale
    q_near = robot.as_q(np.radians(args.near)) if args.near is not None else None
    tolerance = None
    if args.limit_tolerance is not None:
        if not args.limit_tolerance >= 0.0:
            raise TeleprogError(f"--limit-tolerance must be zero or more degrees; got {args.limit_tolerance}")
        tolerance = float(np.radians(args.limit_tolerance))
    if positions_tool_only(robot):
        if args.rpy is not None:
            raise TeleprogError(f"robot {robot.name!r} positions its tool point only; drop --rpy")
        solutions = solve_ik(robot, position=xyz, q_near=q_near, respect_limits=not args.ignore_limits, limit_tolerance=tolerance)
    else:
        if args.rpy is None:
            raise TeleprogError(f"robot {robot.name!r} needs an orientation: add --rpy R P Y (deg)")
        solutions = solve_ik(
            robot, pose_to_transform(xyz, np.radians(args.rpy)), q_near=q_near,
            respect_limits=not args.ignore_limits, limit_tolerance=tolerance,
        )
    if not solutions:
        limits = "" if args.ignore_limits else " within the joint ranges (try --ignore-limits)"
        raise TeleprogError(f"no inverse-kinematics solution for {robot.name!r} at that target{limits}")
    if args.all_turns:
        shown = [(s, 1) for s in solutions]
    else:
        shown = distinct_branches(solutions)
    degs = [np.degrees(s).round(6).tolist() for s, _ in shown]
    turns = [n for _, n in shown]
    if args.json:
        out: dict = {"solutions": degs, "unit": "deg"}
        if not args.all_turns:
            out["turn_variants"] = turns
        print_json(out)
    else:
        for i, (s, n) in enumerate(zip(degs, turns), start=1):
            extra = f"  (+{n - 1} whole-turn variant{'s' if n > 2 else ''})" if n > 1 else ""
            print(f"{i}: " + "  ".join(f"{v:9.3f}" for v in s) + "  deg" + extra)
    return 0



def register(sub: argparse._SubParsersAction) -> None:
    kin = sub.add_parser("kin", help="forward and inverse kinematics")
    kin_sub = kin.add_subparsers(dest="kin_command", required=True, parser_class=type(kin))
    fk = kin_sub.add_parser("fk", help="tool pose in the base frame for a joint vector")
    fk.add_argument("--robot", required=True, help="puma562, rover, or a .urdf/.toml file")
    fk.add_argument("--deg", type=float, nargs="+", required=True, metavar="Q", help="joint angles in degrees")
    fk.add_argument("--ignore-limits", action="store_true", help="accept joint angles outside the ranges")
    fk.add_argument("--json", action="store_true")
    fk.set_defaults(handler=_cmd_kin_fk)
    ik = kin_sub.add_parser("ik", help="all joint solutions for a tool target in the base frame")
    ik.add_argument("--robot", required=True, help="puma562, rover, or a .urdf/.toml file")
    ik.add_argument("--xyz", type=float, nargs=3, required=True, metavar=("X", "Y", "Z"), help="tool position")
    ik.add_argument("--unit", choices=("m", "mm"), default="m", help="unit of --xyz (default m)")
    ik.add_argument("--rpy", type=float, nargs=3, metavar=("R", "P", "Y"), help="tool roll pitch yaw in degrees")
    ik.add_argument("--near", type=float, nargs="+", metavar="Q", help="sort solutions nearest to this joint vector (deg)")
    ik.add_argument("--ignore-limits", action="store_true", help="return every solution, ignoring joint ranges")
    ik.add_argument("--limit-tolerance", type=float, metavar="DEG",
                    help="take a solution this far past a joint limit, at the limit (default: the robot file's "
                         "ik_limit_tolerance; the rover's is 0.5 deg, the others' 0)")
    ik.add_argument("--all-turns", action="store_true",
                    help="list every whole-turn variant of a posture (default: the nearest of each, with their count)")
    ik.add_argument("--json", action="store_true")
    ik.set_defaults(handler=_cmd_kin_ik)
