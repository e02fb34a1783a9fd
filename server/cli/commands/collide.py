"""``teleprog collide``: check the robot at a joint vector against its cell (collision core).

Prints whether anything interferes, the interfering body pairs with their triangle ids (the
ones the console paints red), the smallest separation over the checked pairs and the control
zone of the tool (thesis 4.2.1).
"""

from __future__ import annotations

import argparse

import numpy as np

from server.cli import print_json


def _cmd_collide(args: argparse.Namespace) -> int:
    from shared.cells.loader import DEFAULT_CELL, load_cell
    from shared.collision import SceneModel, zone

    cell = load_cell(args.cell or DEFAULT_CELL)
    robot = cell.robot
    q = robot.as_q(np.radians(args.deg))
    if not args.ignore_limits:
        robot.check_limits(q)
    model = SceneModel.from_cell(cell)
    report = model.check(q, distances="all", triangles=True)
    state = zone(model, cell, q)
    pairs = [
        {"a": p.a, "b": p.b, "triangles_a": p.tris_a.tolist(), "triangles_b": p.tris_b.tolist()} for p in report.pairs
    ]
    min_distance = report.min_distance if report.min_distance is not None else None
    if args.json:
        print_json(
            {
                "collision": report.colliding,
                "pairs": pairs,
                "min_distance": min_distance,
                "nearest": [report.nearest.a, report.nearest.b] if report.nearest is not None else None,
                "zone": state.zone,
                "zone_object": state.object,
                "tool_distance": state.distance if np.isfinite(state.distance) else None,
                "unit": "m",
            }
        )
        return 0
    print(f"collision: {'yes' if report.colliding else 'no'}")
    for p in pairs:
        print(f"  {p['a']} / {p['b']}: {len(p['triangles_a'])} and {len(p['triangles_b'])} triangles interfere")
    if report.nearest is not None:
        print(f"min distance: {report.min_distance * 1e3:.3f} mm ({report.nearest.a} / {report.nearest.b})")
    where = f" (nearest {state.nearest}, {state.distance * 1e3:.3f} mm)" if state.nearest else ""
    print(f"zone: {state.zone}{where}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("collide", help="collision check of the robot at a joint vector in a cell")
    p.add_argument("--cell", default=None, help="cell file (default assets/cells/peg_in_hole.toml)")
    p.add_argument("--deg", type=float, nargs="+", required=True, metavar="Q", help="joint angles in degrees")
    p.add_argument("--ignore-limits", action="store_true", help="accept joint angles outside the ranges")
    p.add_argument("--json", action="store_true", help="print JSON (distances in metres)")
    p.set_defaults(handler=_cmd_collide)
