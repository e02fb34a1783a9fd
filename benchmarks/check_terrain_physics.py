"""Cross-check of the rover cells' ground: the console's terrain verdict against the physics
world's contact, over arm placements.

For each placement q (joint vector within the limits) the console asks its terrain checker
(``shared.terrain``: the exact arm-to-mesh distance, contact when ``min_distance(q) <= 0``, and the
paper's virtual sensors, ``sensor_check(q).in_collision``); the physics world (MuJoCo, the ground
as the height field of ``robot_sim.physics.terrain``) sets the arm's joints to q (the compliant
wrist at rest), runs ``mj_forward`` and looks for a contact between an arm geom and the height
field with ``dist <= 0``. Three sets of placements:

* ``uniform``: joint vectors drawn uniformly within the limits (seeded);
* ``near``: drawn from the region of ``assets/programs/rover_placement.tp`` (the instrument over
  the ground: azimuth -27 +- 25 deg, shoulder -10..-50 deg, elbow -150..-270 deg) and kept when
  the console's distance is within ``--band-mm`` of the ground, the placements where the two
  models can disagree;
* ``program``: the program's own poses, its placement lowered on joint 2 from -30 to -40 deg.

Every disagreement is listed with the console's distance, the shape nearest the ground, the
physics contact depth, and the height field's error against the mesh under the console's witness
point (the grid's resolution), which is what explains a verdict that flips within it.

    .venv/bin/python benchmarks/check_terrain_physics.py [--cell assets/cells/rover_terrain.toml]
        [--uniform 200] [--near 200] [--band-mm 0.3] [--seed 0] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def _reference_path() -> None:
    root = Path(__file__).resolve().parents[1]
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))


_reference_path()

#: the placement region of assets/programs/rover_placement.tp (deg): centre, half-range
_REGION_LO = np.array([-52.0, -50.0, -270.0])
_REGION_HI = np.array([-2.0, -10.0, -150.0])


class PhysicsProbe:
    """The physics world's model of a cell, posed statically: arm joints set, the rest at rest."""

    def __init__(self, cell) -> None:
        import mujoco

        from robot_sim.settings import WorldSettings
        from robot_sim.worlds import make_world

        self.mj = mujoco
        t = time.perf_counter()
        world = make_world(cell, WorldSettings())
        self.build_s = time.perf_counter() - t
        self.model = world.model
        self.data = mujoco.MjData(self.model)
        self.qadr = world._qadr
        self.xml_bytes = len(world.layout.xml)
        self.terrain = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, "terrain/hfield")
        if self.terrain < 0:
            raise SystemExit("the physics model has no terrain/hfield geom")
        self.arm = np.asarray(self.model.geom_contype) == 2
        self.dof = cell.robot.dof
        hf = int(self.model.geom_dataid[self.terrain])
        self.hfield = (int(self.model.hfield_nrow[hf]), int(self.model.hfield_ncol[hf]),
                       [float(v) for v in self.model.hfield_size[hf]])

    def label(self, geom: int) -> str:
        """``link<i>#<k>``: the k-th shape of link i, as the console numbers them."""
        name = self.mj.mj_id2name(self.model, self.mj.mjtObj.mjOBJ_GEOM, geom) or f"geom{geom}"
        body, _, k = name.partition("/")
        if body == "gripper":
            body = f"link{self.dof}"
        return f"{body}#{k}"

    def contact(self, q: np.ndarray) -> tuple[bool, float, list[str]]:
        """(contact with the ground, deepest penetration dist (<= 0; +inf if none), arm shapes)."""
        d = self.data
        d.qpos[:] = 0.0
        d.qvel[:] = 0.0
        d.qpos[self.qadr] = q
        self.mj.mj_forward(self.model, d)
        deepest, shapes = np.inf, set()
        for c in d.contact[: d.ncon]:
            g1, g2 = int(c.geom1), int(c.geom2)
            if self.terrain not in (g1, g2):
                continue
            other = g2 if g1 == self.terrain else g1
            if not self.arm[other] or c.dist > 0.0:
                continue
            deepest = min(deepest, float(c.dist))
            shapes.add(self.label(other))
        return bool(shapes), deepest, sorted(shapes)


def _console_label(shape_name: str) -> str:
    """``link3.cylinder3`` -> ``link3#3``."""
    link, _, rest = shape_name.partition(".")
    k = "".join(ch for ch in rest if ch.isdigit())
    return f"{link}#{k}"


def _below_ground(checker, ground, q: np.ndarray) -> list[str]:
    """The arm shapes whose centre lies under the ground surface (``ground(x, y)``: its height)."""
    _, ts = checker.arm.shape_poses(checker.world_T_base, q)
    under = ts[:, 2] < ground(ts[:, 0], ts[:, 1])
    return [_console_label(checker.arm.shapes[i].name) for i in np.flatnonzero(under)]


def _boundary(checker, ground, q: np.ndarray, lo: float, hi: float, joint: int = 1, samples: int = 17):
    """Joint ``joint``'s value where the arm, at ``q`` otherwise, comes down onto the ground: the
    clear end of the first clear/contact change over the joint's range whose clear side has the
    whole arm above the ground. Returns (value, direction into the ground, an ``under`` placement
    met on the way or None), or None."""
    vals = np.linspace(lo, hi, samples)
    touch = []
    for v in vals:
        qq = q.copy()
        qq[joint] = v
        touch.append(checker.min_distance(qq) <= 0.0)
    under = None
    for k in range(samples - 1):
        if touch[k] != touch[k + 1]:
            a, b = (vals[k], vals[k + 1]) if not touch[k] else (vals[k + 1], vals[k])  # a clear, b touching
            qa = q.copy()
            qa[joint] = a
            if _below_ground(checker, ground, qa):
                under = qa  # clear for the console, yet part of the arm is under the ground
                continue
            for _ in range(40):
                m = 0.5 * (a + b)
                qq = q.copy()
                qq[joint] = m
                if checker.min_distance(qq) <= 0.0:
                    b = m
                else:
                    a = m
            return a, np.sign(b - a), under
    return None if under is None else (None, 0.0, under)


def placements(robot, n_uniform: int, n_near: int, band: float, seed: int, checker, ground,
               n_under: int = 20) -> list[tuple[str, np.ndarray, float | None]]:
    """(set, q, signed offset from the ground in m (an estimate on the contact side; None for the
    other sets))."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(robot.lower, float), np.asarray(robot.upper, float)
    out: list = [("uniform", rng.uniform(lo, hi), None) for _ in range(n_uniform)]
    # near the ground: a pose of the program's region, joint 2 (the shoulder, which lowers the
    # instrument) moved to where the arm comes down onto the ground, then off it by a signed
    # amount drawn uniformly in +-band: on the clear side the console's distance is that amount,
    # on the contact side the depth is its first-order estimate (the clearance's rate of change
    # on the clear side). Poses met on the way with part of the arm wholly under the ground (the
    # console clear, as its ground is a surface) are the ``under`` set.
    rlo = np.maximum(np.radians(_REGION_LO), lo)
    rhi = np.minimum(np.radians(_REGION_HI), hi)
    near, under, tries = [], [], 0
    while len(near) < n_near and tries < 20 * max(n_near, 1):
        tries += 1
        q = rng.uniform(rlo, rhi)
        found = _boundary(checker, ground, q, lo[1], hi[1])
        if found is None:
            continue
        q2, into, q_under = found
        if q_under is not None and len(under) < n_under:
            under.append(("under", q_under, None))
        if q2 is None:
            continue
        probe = q.copy()
        probe[1] = q2 - into * 1e-3
        rate = checker.min_distance(probe) / 1e-3  # m of clearance per rad, leaving the ground
        if not rate > 0.0:
            continue
        offset = rng.uniform(-band, band)
        q = q.copy()
        q[1] = q2 - into * offset / rate
        if lo[1] <= q[1] <= hi[1]:
            near.append(("near", q, offset))
    out += near + under
    # the program's placement: over the target, then lowered on joint 2 (DRIVE J2 TO -35 deg)
    for j2 in np.linspace(-30.0, -40.0, 21):
        out.append(("program", np.radians([-27.0, j2, -210.0]), None))
    return out


def run(cell_path: str, n_uniform: int, n_near: int, band_mm: float, seed: int) -> dict:
    from robot_sim.physics.terrain import cell_height_grid, rasterise
    from shared.cells.loader import load_cell
    from shared.terrain.cell import load_cell_terrain

    cell = load_cell(cell_path)
    terrain = load_cell_terrain(cell)
    checker = terrain.checker
    probe = PhysicsProbe(cell)
    grid = cell_height_grid(cell)
    mesh = terrain.mesh
    band = band_mm * 1e-3
    ground = grid.height_at
    rows = []
    t_console = t_physics = 0.0
    for kind, q, offset in placements(cell.robot, n_uniform, n_near, band, seed, checker, ground):
        t = time.perf_counter()
        rep = checker.exact_check(q, per_shape=True)
        sensors = checker.sensor_check(q).in_collision
        t_console += time.perf_counter() - t
        t = time.perf_counter()
        hit, depth, shapes = probe.contact(q)
        t_physics += time.perf_counter() - t
        x, y = rep.world_p_terrain[:2]
        z_mesh = float(rasterise(mesh.vertices, mesh.faces, x, y, 1.0, 1, 1)[0, 0])
        z_grid = float(grid.height_at(x, y))
        rows.append({
            "set": kind, "q_deg": [round(float(v), 3) for v in np.degrees(q)],
            "offset_mm": None if offset is None else round(offset * 1e3, 4),
            "console_distance_mm": round(rep.distance * 1e3, 4), "console_contact": rep.in_collision,
            "console_shape": _console_label(rep.shape) if rep.shape else "",
            "console_contact_shapes": sorted(_console_label(k) for k, v in rep.per_shape.items() if v <= 0.0),
            "sensor_contact": bool(sensors),
            "physics_contact": hit, "physics_depth_mm": None if not hit else round(-depth * 1e3, 4),
            "physics_shapes": shapes,
            "shapes_under_ground": _below_ground(checker, ground, q),
            "grid_minus_mesh_mm": round((z_grid - z_mesh) * 1e3, 4) if np.isfinite(z_mesh) else None,
        })
        if rows[-1]["console_contact"] != rows[-1]["physics_contact"]:
            d_grid = grid_distance(grid, checker, q, rep.world_p_terrain)
            rows[-1]["grid_exact_distance_mm"] = round(d_grid * 1e3, 4)
    return summarise(cell, probe, grid, rows, band_mm, t_console, t_physics)


#: half width (m) of the height-field patch the grid's exact distance is taken over
_PATCH = 0.12


def grid_distance(grid, checker, q: np.ndarray, centre: np.ndarray) -> float:
    """The console's exact distance from the arm to the height field's own triangles (MuJoCo's
    split of each grid cell) over a patch around ``centre``: the surface the physics collides with,
    measured by the console's exact check. It tells the grid's resolution (mesh against grid)
    from MuJoCo's collider (grid against the physics contact)."""
    from shared.terrain.checks import TerrainChecker
    from shared.terrain.tree import build_tree
    from shared.terrain.triangulate import TerrainMesh

    v, f = grid.triangles(centre[:2] - _PATCH, centre[:2] + _PATCH)
    return TerrainChecker(build_tree(TerrainMesh(v, f)), checker.arm, checker.world_T_base).min_distance(q)


def _why(r: dict, h_mm: float) -> str:
    """Why the verdicts differ: the grid's resolution (the console's exact check on the height
    field's own triangles sides with the physics) or MuJoCo's collider (it sides with the console)."""
    d_grid = r.get("grid_exact_distance_mm")
    off = r["offset_mm"]
    where = (f"{off:+.4f} mm from the mesh" if off is not None else f"console distance {r['console_distance_mm']} mm")
    if d_grid is None:  # (a ground-truth distance is taken for every disagreement)
        return ""
    grid_contact = d_grid <= 0.0
    if r["physics_contact"] and not r["console_contact"] and r["shapes_under_ground"]:
        return (f"under the ground: {', '.join(r['shapes_under_ground'])} has its centre below the surface, clear of "
                f"the console's ground (a surface of triangles, {d_grid:.3f} mm from the grid's); the height field is a solid")
    if grid_contact == r["physics_contact"]:
        side = "below" if r["console_contact"] else "above"
        return (f"resolution: the arm is {where}; the height field ({h_mm:.2f} mm grid) lies {side} the mesh there: "
                f"on its triangles the arm is {'in contact' if grid_contact else f'{d_grid:.4f} mm clear'}")
    if "link0" in r["console_shape"]:
        return "the base is welded to the world: MuJoCo does not collide it with the static ground"
    return (f"collider: the arm is {where} and {'touches' if grid_contact else f'{d_grid:.4f} mm clear of'} the height "
            f"field's triangles, MuJoCo's hfield contact {'finds none' if grid_contact else 'reports one'}")


def summarise(cell, probe: PhysicsProbe, grid, rows: list[dict], band_mm: float, t_console: float, t_physics: float) -> dict:
    h_mm = grid.h * 1e3
    sets = {}
    for name in ("uniform", "near", "under", "program", "all"):
        rs = [r for r in rows if name == "all" or r["set"] == name]
        if not rs:
            continue
        agree = sum(r["console_contact"] == r["physics_contact"] for r in rs)
        sensor_agree = sum(r["sensor_contact"] == r["physics_contact"] for r in rs)
        sets[name] = {
            "placements": len(rs), "agree": agree, "disagree": len(rs) - agree,
            "both_contact": sum(r["console_contact"] and r["physics_contact"] for r in rs),
            "both_clear": sum(not r["console_contact"] and not r["physics_contact"] for r in rs),
            "console_only": sum(r["console_contact"] and not r["physics_contact"] for r in rs),
            "physics_only": sum(r["physics_contact"] and not r["console_contact"] for r in rs),
            "sensors_agree_with_physics": sensor_agree,
        }
    disagreements = []
    for r in rows:
        if r["console_contact"] != r["physics_contact"]:
            disagreements.append({**r, "why": _why(r, h_mm)})
    # the boundary: the largest |console distance| at which the verdicts still differ
    worst = max((abs(r["console_distance_mm"]) for r in disagreements), default=0.0)
    errs = np.array([abs(r["grid_minus_mesh_mm"]) for r in rows if r["grid_minus_mesh_mm"] is not None])
    nrow, ncol, size = probe.hfield
    return {
        "cell": cell.name, "band_mm": band_mm,
        "hfield": {"nrow": nrow, "ncol": ncol, "cell_mm": round(h_mm, 4), "size_m": [round(v, 6) for v in size],
                   "xml_bytes": probe.xml_bytes, "world_build_s": round(probe.build_s, 3)},
        "sets": sets,
        "largest_disagreeing_distance_mm": round(worst, 4),
        "grid_error_at_witness_mm": {"median": round(float(np.median(errs)), 5) if len(errs) else None,
                                     "max": round(float(errs.max()), 5) if len(errs) else None},
        "time_per_placement_ms": {"console": round(t_console / max(len(rows), 1) * 1e3, 3),
                                  "physics": round(t_physics / max(len(rows), 1) * 1e3, 3)},
        "disagreements": disagreements,
        "placements": rows,
    }


def markdown(res: dict) -> str:
    h = res["hfield"]
    out = [f"### {res['cell']}: console terrain verdict vs physics contact", "",
           f"Height field {h['nrow']} x {h['ncol']} nodes, {h['cell_mm']} mm cells, size {h['size_m']} m; "
           f"model XML {h['xml_bytes'] / 1e6:.2f} MB, world built in {h['world_build_s']} s.", "",
           "| set | placements | agree | both contact | both clear | console only | physics only | sensors agree w/ physics |",
           "|---|---|---|---|---|---|---|---|"]
    for name, s in res["sets"].items():
        out.append(f"| {name} | {s['placements']} | {s['agree']} | {s['both_contact']} | {s['both_clear']} | "
                   f"{s['console_only']} | {s['physics_only']} | {s['sensors_agree_with_physics']} |")
    g = res["grid_error_at_witness_mm"]
    out += ["", f"Near set: console distance within +-{res['band_mm']} mm. Height field minus mesh under the "
                f"console's witness point: median {g['median']} mm, max {g['max']} mm. Per placement: console "
                f"{res['time_per_placement_ms']['console']} ms (exact + sensors), physics "
                f"{res['time_per_placement_ms']['physics']} ms (mj_forward)."]
    dis = res["disagreements"]
    out += ["", f"Disagreements: {len(dis)} (largest |console distance| among them "
                f"{res['largest_disagreeing_distance_mm']} mm)"]
    if dis:
        out += ["", "| set | q (deg) | console d (mm) | console shape | physics depth (mm) | physics shapes | grid - mesh (mm) | why |",
                "|---|---|---|---|---|---|---|---|"]
        for r in dis:
            out.append(f"| {r['set']} | {r['q_deg']} | {r['console_distance_mm']} | {r['console_shape']} | "
                       f"{r['physics_depth_mm']} | {', '.join(r['physics_shapes'])} | {r['grid_minus_mesh_mm']} | {r['why']} |")
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cell", action="append", help="cell file (repeatable; default rover_terrain)")
    p.add_argument("--uniform", type=int, default=200, help="placements drawn uniformly within the joint limits")
    p.add_argument("--near", type=int, default=200, help="placements within --band-mm of the ground")
    p.add_argument("--band-mm", type=float, default=0.3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--all-rows", action="store_true", help="keep every placement's row in the JSON")
    args = p.parse_args(argv)
    root = Path(__file__).resolve().parents[1]
    cells = args.cell or [str(root / "assets/cells/rover_terrain.toml")]
    results = []
    for c in cells:
        res = run(c, args.uniform, args.near, args.band_mm, args.seed)
        if not args.all_rows:
            res.pop("placements")
        results.append(res)
    if args.json:
        print(json.dumps(results if len(results) > 1 else results[0], indent=1))
    else:
        print("\n\n".join(markdown(r) for r in results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
