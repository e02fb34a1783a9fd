"""``teleprog terrain``: the lunar-rover terrain tools (seed 004).

    teleprog terrain generate --out FILE   seeded synthetic lunar terrain (cloud or --mesh)
    teleprog terrain info FILE             load, filter, triangulate and build the tree; sizes, times
    teleprog terrain check --deg Q1 Q2 Q3  exact distance and virtual-sensor check of a pose
    teleprog terrain place --target X Y Z  instrument placement at a terrain point, with its program
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from server.cli import print_json
from shared.errors import InputError

DEFAULT_CELL = "assets/cells/rover_terrain.toml"


def _cmd_generate(args: argparse.Namespace) -> int:
    from shared.terrain.cloud import ply_bytes
    from shared.terrain.filter import grid_density_filter
    from shared.terrain.generator import generate_points, make_spec
    from shared.terrain.triangulate import triangulate_25d

    if args.points < 3:
        raise InputError(f"--points must be at least 3, got {args.points}")
    out = Path(args.out)
    if not out.parent.is_dir():
        raise InputError(f"--out: folder {out.parent} does not exist")
    spec = make_spec(args.seed, (args.origin[0] * 1e-3, args.origin[1] * 1e-3), (args.size[0] * 1e-3, args.size[1] * 1e-3))
    points = generate_points(spec, args.points, args.noise * 1e-3)
    suffix = out.suffix.lower()
    faces = None
    if args.mesh:
        if suffix != ".ply":
            raise InputError("--mesh writes a PLY file: give --out a .ply name")
        points = points[grid_density_filter(points)]
        faces = triangulate_25d(points).faces
    if suffix == ".ply":
        out.write_bytes(ply_bytes(points, faces, comment=f"teleprog synthetic lunar terrain seed {args.seed} (m)"))
    elif suffix == ".npy":
        np.save(out, points)
    elif suffix in (".xyz", ".csv", ".txt"):
        np.savetxt(out, points, fmt="%.6f", delimiter="," if suffix == ".csv" else " ")
    else:
        raise InputError(f"--out: unknown type {suffix or '(none)'!r}; valid: .ply, .npy, .xyz, .csv, .txt")
    summary = {"file": str(out), "points": int(len(points)), "triangles": int(len(faces)) if faces is not None else 0,
               "seed": args.seed, "craters": len(spec.craters), "rocks": len(spec.rocks), "unit": "m"}
    if args.json:
        print_json(summary)
    else:
        tri = f", {summary['triangles']} triangles" if faces is not None else ""
        print(f"wrote {out}: {len(points)} points{tri} (seed {args.seed}, {len(spec.craters)} craters, {len(spec.rocks)} rocks)")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from shared.terrain.cloud import load_point_cloud
    from shared.terrain.filter import grid_density_filter
    from shared.terrain.tree import build_tree
    from shared.terrain.triangulate import triangulate_25d

    t0 = time.perf_counter()
    cloud = load_point_cloud(args.file, unit=args.unit, up=args.up)
    t1 = time.perf_counter()
    keep = grid_density_filter(cloud.points, spacing=args.spacing * 1e-3 if args.spacing else None)
    t2 = time.perf_counter()
    mesh = triangulate_25d(cloud.points[keep])
    t3 = time.perf_counter()
    tree = build_tree(mesh)
    t4 = time.perf_counter()
    info = {"file": str(args.file), "points": len(cloud), "kept": int(len(keep)), "triangles": mesh.n_triangles,
            "tree_depth": tree.depth, "tree_mb": tree.nbytes / 1e6,
            "seconds": {"load": t1 - t0, "filter": t2 - t1, "triangulate": t3 - t2, "tree": t4 - t3}}
    if args.json:
        print_json(info)
    else:
        print(f"{args.file}: {len(cloud)} points, {len(keep)} kept by the grid filter, {mesh.n_triangles} triangles, "
              f"tree depth {tree.depth} ({tree.nbytes / 1e6:.1f} MB)")
        print("  load {load:.2f} s, filter {filter:.2f} s, triangulate {triangulate:.2f} s, tree {tree:.2f} s".format(**info["seconds"]))
    return 0


def _cell_terrain(path: str):
    from shared.cells.loader import load_cell
    from shared.terrain.cell import load_cell_terrain

    cell = load_cell(path)
    return cell, load_cell_terrain(cell)


def _head_sensors(terrain, sensors) -> dict:
    """The instrument-head part's sensors (seed 004's E\\5, numbered 1..n as in Tables 3-5):
    per sensor whether it collides or its clearance d_RS (m; None when its ray meets nothing)."""
    from shared.terrain.arm import head_part

    index = head_part(terrain.arm)
    mine = np.flatnonzero(sensors.part == index)
    rows = [{"index": k, "collides": bool(sensors.collides[i]),
             "distance": None if sensors.collides[i] or not np.isfinite(sensors.d_RS[i]) else float(sensors.d_RS[i])}
            for k, i in enumerate(mine, start=1)]
    clear = [r["distance"] for r in rows if r["distance"] is not None]
    return {"part": terrain.arm.parts[index].name, "count": len(rows), "colliding": sum(r["collides"] for r in rows),
            "in_collision": any(r["collides"] for r in rows),
            "distance": 0.0 if any(r["collides"] for r in rows) else (min(clear) if clear else None), "sensors": rows}


def _cmd_check(args: argparse.Namespace) -> int:
    cell, terrain = _cell_terrain(args.cell)
    q = cell.robot.as_q(np.radians(args.deg))
    cell.robot.check_limits(q)
    exact = terrain.checker.exact_check(q, per_shape=True)
    sensors = terrain.checker.sensor_check(q)
    head = _head_sensors(terrain, sensors)
    if args.json:
        print_json({
            "exact": {"distance": exact.distance, "in_collision": exact.in_collision, "shape": exact.shape,
                      "world_p_arm": exact.world_p_arm.tolist(), "world_p_terrain": exact.world_p_terrain.tolist(),
                      "triangle": exact.triangle, "contact_triangles": exact.contact_triangles.tolist(),
                      "per_shape": exact.per_shape},
            "sensors": {"distance": sensors.distance, "in_collision": sensors.in_collision,
                        "colliding": int(sensors.collides.sum()), "count": int(len(sensors.d_S)),
                        "d_RS": [None if not np.isfinite(v) else float(v) for v in sensors.d_RS]},
            "head_part": head,
            "unit": "m",
        })
        return 0
    state = "CONTACT" if exact.in_collision else "clear"
    print(f"exact: {state}, minimum distance {exact.distance * 1e3:.3f} mm at {exact.shape} (triangle {exact.triangle})")
    print(f"  arm point ({', '.join(f'{v * 1e3:.1f}' for v in exact.world_p_arm)}) mm, "
          f"terrain point ({', '.join(f'{v * 1e3:.1f}' for v in exact.world_p_terrain)}) mm")
    if exact.in_collision:
        print(f"  {len(exact.contact_triangles)} terrain triangles touch the arm")
    s_state = "collision" if sensors.in_collision else f"clear, distance {sensors.distance * 1e3:.1f} mm"
    print(f"virtual sensors: {s_state} ({int(sensors.collides.sum())} of {len(sensors.d_S)} sensors collide)")
    h_state = (f"{head['colliding']} of {head['count']} sensors collide" if head["in_collision"] else
               "clear" + ("" if head["distance"] is None else f", distance {head['distance'] * 1e3:.1f} mm"))
    print(f"instrument-head part (seed 004's E\\5: {head['part']}): {h_state}")

    def cell_text(r: dict) -> str:
        what = "collides" if r["collides"] else "no reading" if r["distance"] is None else f"{r['distance']:.3f} m"
        return f"{r['index']:>3} {what}"

    cells = [cell_text(r) for r in head["sensors"]]
    rows = -(-len(cells) // 3)
    for i in range(rows):
        print("  " + "    ".join(c.ljust(14) for c in cells[i::rows]).rstrip())
    return 0


def _cmd_place(args: argparse.Namespace) -> int:
    from shared.language.formatter import format_program
    from shared.terrain.placement import plan_placement, require_placement

    cell, terrain = _cell_terrain(args.cell)
    from shared.terrain.placement import terrain_point_at

    if len(args.target) not in (2, 3):
        raise InputError("--target takes X Y (the terrain point below) or X Y Z, in mm")
    target = np.array(args.target, dtype=float) * 1e-3
    if len(target) == 2:
        target = terrain_point_at(terrain.checker, float(target[0]), float(target[1]))
    t0 = time.perf_counter()
    result = plan_placement(terrain.checker, target, max_standoff=args.standoff * 1e-3, margin=args.margin * 1e-3)
    elapsed = time.perf_counter() - t0
    best = require_placement(result)
    text = format_program(result.program)
    if args.json:
        print_json({
            "normal": result.world_n_surface.tolist(), "seconds": elapsed, "program": text,
            "candidates": [{"q_deg": np.degrees(c.q).tolist(), "standoff": c.standoff, "clearance": c.clearance,
                            "head_clearance": c.head_clearance, "tilt_deg": float(np.degrees(c.tilt)),
                            "approach_deg": None if c.q_approach is None else np.degrees(c.q_approach).tolist()}
                           for c in result.candidates],
            "rejected": result.rejected, "unit": "m",
        })
        return 0
    print(f"{len(result.candidates)} placement(s) in {elapsed * 1e3:.0f} ms; surface normal "
          f"({', '.join(f'{v:.3f}' for v in result.world_n_surface)})")
    for i, c in enumerate(result.candidates, start=1):
        print(f"{i}: q = ({', '.join(f'{v:.2f}' for v in np.degrees(c.q))}) deg, C {c.standoff * 1e3:.0f} mm above, "
              f"arm clearance {c.clearance * 1e3:.1f} mm, head {c.head_clearance * 1e3:.1f} mm, tilt {np.degrees(c.tilt):.1f} deg")
    print(f"program for #1 (q = {', '.join(f'{v:.2f}' for v in np.degrees(best.q))} deg):")
    print(text, end="")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("terrain", help="lunar terrain: generate, inspect, check a pose, place the instrument")
    tsub = p.add_subparsers(dest="terrain_command", required=True, parser_class=type(p))

    g = tsub.add_parser("generate", help="write a seeded synthetic lunar terrain (craters, rocks, slope)")
    g.add_argument("--out", required=True, help="output file: .ply (binary), .npy, .xyz, .csv")
    g.add_argument("--points", type=int, default=400_000, help="number of points (default 400000)")
    g.add_argument("--seed", type=int, default=4, help="random seed (default 4)")
    g.add_argument("--origin", type=float, nargs=2, default=(0.0, -1000.0), metavar=("X", "Y"), help="corner, mm")
    g.add_argument("--size", type=float, nargs=2, default=(2000.0, 2000.0), metavar=("W", "H"), help="extent, mm")
    g.add_argument("--noise", type=float, default=0.5, help="height noise (1 sigma), mm")
    g.add_argument("--mesh", action="store_true", help="filter and triangulate; write the mesh (PLY)")
    g.add_argument("--json", action="store_true")
    g.set_defaults(handler=_cmd_generate)

    i = tsub.add_parser("info", help="load a point cloud, filter, triangulate, build the tree")
    i.add_argument("file")
    i.add_argument("--unit", choices=("m", "mm"), default="m", help="length unit of the file")
    i.add_argument("--up", default="z", help="file axis pointing up: x, y, z, -x, -y, -z")
    i.add_argument("--spacing", type=float, default=None, help="grid-filter spacing, mm (default from density)")
    i.add_argument("--json", action="store_true")
    i.set_defaults(handler=_cmd_info)

    c = tsub.add_parser("check", help="exact distance and virtual-sensor check of an arm pose")
    c.add_argument("--cell", default=DEFAULT_CELL)
    c.add_argument("--deg", type=float, nargs="+", required=True, help="joint angles, deg")
    c.add_argument("--json", action="store_true")
    c.set_defaults(handler=_cmd_check)

    pl = tsub.add_parser("place", help="instrument placement at a terrain point")
    pl.add_argument("--cell", default=DEFAULT_CELL)
    pl.add_argument("--target", type=float, nargs="+", required=True,
                    help="world point X Y Z, or X Y for the terrain point there; mm")
    pl.add_argument("--standoff", type=float, default=30.0, help="largest distance of C from the surface, mm")
    pl.add_argument("--margin", type=float, default=20.0, help="clearance of the rest of the arm, mm")
    pl.add_argument("--json", action="store_true")
    pl.set_defaults(handler=_cmd_place)
