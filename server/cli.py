"""The one command line: ``teleprog <subcommand>``.

Errors the project raises on purpose print one line on stderr and exit 1; usage errors exit 2
(argparse). ``--json`` prints machine-readable output on stdout.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Callable, Sequence

import numpy as np

from shared.errors import TeleprogError

log = logging.getLogger("teleprog")

Handler = Callable[[argparse.Namespace], int]


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line usage error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def _print_json(obj: object) -> None:
    print(json.dumps(obj))


# -- kin ----------------------------------------------------------------------------------------
def _cmd_kin_fk(args: argparse.Namespace) -> int:
    from shared.robots.loader import load_robot

    robot = load_robot(args.robot)
    q = robot.as_q(np.radians(args.deg))
    if not args.ignore_limits:
        robot.check_limits(q)
    base_T_tool = robot.fk(q)
    if args.json:
        _print_json({"position": base_T_tool[:3, 3].tolist(), "rotation": base_T_tool[:3, :3].tolist(), "unit": "m"})
    else:
        x, y, z = base_T_tool[:3, 3] * 1e3
        print(f"{robot.name} tool in base frame: x={x:.3f} mm y={y:.3f} mm z={z:.3f} mm")
        for row in base_T_tool[:3, :3]:
            print("  [" + "  ".join(f"{v: .6f}" for v in row) + "]")
    return 0


def _cmd_kin_ik(args: argparse.Namespace) -> int:
    from shared.robots.ik import solve_ik
    from shared.robots.loader import load_robot
    from shared.spatial import pose_to_transform

    robot = load_robot(args.robot)
    scale = 1e-3 if args.unit == "mm" else 1.0
    xyz = np.array(args.xyz) * scale
    q_near = robot.as_q(np.radians(args.near)) if args.near is not None else None
    if robot.description.ik == "rover" or robot.dof < 6:
        if args.rpy is not None:
            raise TeleprogError(f"robot {robot.name!r} positions its tool point only; drop --rpy")
        solutions = solve_ik(robot, position=xyz, q_near=q_near, respect_limits=not args.ignore_limits)
    else:
        if args.rpy is None:
            raise TeleprogError(f"robot {robot.name!r} needs an orientation: add --rpy R P Y (deg)")
        solutions = solve_ik(
            robot, pose_to_transform(xyz, np.radians(args.rpy)), q_near=q_near, respect_limits=not args.ignore_limits
        )
    if not solutions:
        limits = "" if args.ignore_limits else " within the joint ranges (try --ignore-limits)"
        raise TeleprogError(f"no inverse-kinematics solution for {robot.name!r} at that target{limits}")
    degs = [np.degrees(s).round(6).tolist() for s in solutions]
    if args.json:
        _print_json({"solutions": degs, "unit": "deg"})
    else:
        for i, s in enumerate(degs, start=1):
            print(f"{i}: " + "  ".join(f"{v:9.3f}" for v in s) + "  deg")
    return 0


# -- up -----------------------------------------------------------------------------------------
def _cmd_up(args: argparse.Namespace) -> int:
    from server.run import run_console

    return run_console(args)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="teleprog", description="Teleprogramming console for a robot arm across seconds of delay")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    kin = sub.add_parser("kin", help="forward and inverse kinematics")
    kin_sub = kin.add_subparsers(dest="kin_command", required=True, parser_class=_Parser)
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
    ik.add_argument("--json", action="store_true")
    ik.set_defaults(handler=_cmd_kin_ik)

    up = sub.add_parser("up", help="start the console (web page, API and 3D scene)")
    up.add_argument("--port", type=int, default=None, help="HTTP port (default 8080)")
    up.add_argument("--host", default=None, help="address to bind (default 127.0.0.1)")
    up.add_argument("--cell", default=None, help="cell file (default assets/cells/peg_in_hole.toml)")
    up.set_defaults(handler=_cmd_up)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    try:
        return int(args.handler(args))
    except TeleprogError as exc:
        print(f"teleprog: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
