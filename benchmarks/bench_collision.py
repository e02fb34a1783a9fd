"""Full scene collision checks and distance queries: this project's core against coal and
python-fcl on the same triangles and the same poses.

    .venv/bin/teleprog bench collision              # table
    .venv/bin/teleprog bench collision --json
    .venv/bin/python benchmarks/bench_collision.py --drag-poses 10000 --random-poses 2000

The peg-in-hole cell (PUMA 562, table, plate, peg). Two pose streams: a recorded-style dragging
motion (straight joint-space runs between random goals in steps of at most 0.004 rad, as the
operator's gizmo produces: consecutive poses close together) and independent random poses within
the joint ranges. Per pose:

* ``check``: the full scene answer the console needs at display rate: does anything interfere,
  which body pairs, and every interfering triangle pair (for red painting). Ours:
  ``SceneModel.check(q, distances="none")`` from the joint vector (forward kinematics included);
  coal and fcl: every checked body pair collided with all contacts (``num_max_contacts`` large),
  from precomputed world poses.
* ``first hit``: the yes/no answer and the interfering pairs, stopping at the first interfering
  triangle pair of each body pair (coal and fcl: ``num_max_contacts = 1``).
* ``distance``: the separation of every checked pair (ours also answers collision and returns
  witness points; coal and fcl: one distance call per pair with nearest points).

The checked pairs are the same for all (the model's pairs: non-adjacent links not declared
always in contact, links against objects, the movable peg against the static objects). Engines
run interleaved in chunks of poses so a machine shared with other jobs slows them alike.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _reference_path() -> None:
    """coal's side of the comparison lives with the collision tests (the cross-check's reference)."""
    for p in (str(ROOT), str(ROOT / "tests" / "collision")):
        if p not in sys.path:
            sys.path.insert(0, p)

CHUNK = 250


# how far the operator's drags wander from the ready pose, per joint (deg)
WORK_SPREAD_DEG = (40.0, 25.0, 25.0, 60.0, 40.0, 90.0)


def work_dragging(cell, n: int, rng: np.random.Generator, step: float = 0.004) -> np.ndarray:
    """Joint vectors as when the operator drags the arm about the work area: straight
    joint-space runs, in steps of at most ``step`` rad (0.23 deg: one display frame of a brisk
    drag), between random goals around the cell's ready pose (``WORK_SPREAD_DEG``), so the
    gripper often touches the table, the plate and the peg. ``(n, dof)``."""
    lo, hi = cell.robot.lower, cell.robot.upper
    spread = np.radians(WORK_SPREAD_DEG)
    q = cell.q_home.copy()
    out: list[np.ndarray] = []
    while len(out) < n:
        goal = np.clip(cell.q_home + rng.uniform(-spread, spread), lo, hi)
        k = max(int(np.abs(goal - q).max() / step), 1)
        for s in np.linspace(0.0, 1.0, k + 1)[1:]:
            out.append(q + s * (goal - q))
        q = goal
    return np.array(out[:n])


class _Engine:
    name = ""

    def check(self, k: int) -> None: ...

    def distance(self, k: int) -> None: ...


class _Ours(_Engine):
    name = "ours"

    def __init__(self, model, qs: np.ndarray) -> None:
        self.model, self.qs = model, qs
        self.data = model.new_data()

    def check(self, k: int) -> None:
        report = self.model.check(self.qs[k], data=self.data, distances="none", triangles=True)
        if report.colliding:  # read the triangle pairs as the others read their contacts
            _ = report.triangle_pairs

    def first_hit(self, k: int) -> None:
        self.model.check(self.qs[k], data=self.data, distances="none", triangles=False)

    def distance(self, k: int) -> None:
        _ = self.model.check(self.qs[k], data=self.data, distances="all", triangles=False).distances

    def reset(self) -> None:
        self.data.reset()


class _Coal(_Engine):
    """coal on the meshes of ``coal_reference.CoalScene`` (the cross-check's reference), called
    in a tight loop over the checked pairs (no per-pair Python bookkeeping beyond reading the
    contacts of colliding pairs)."""

    name = "coal"

    def __init__(self, model, worlds: np.ndarray, mode: np.ndarray) -> None:
        import coal

        from coal_reference import CoalScene

        self.coal = coal
        scene = CoalScene(model)
        self.objects = scene.objects
        self.pairs = [(scene.objects[a], scene.objects[b]) for (a, b), m in zip(scene.pairs, mode) if m > 0]
        self.creq, self.creq1, self.dreq = scene.creq, scene.creq_first, scene.dreq
        self.tf = [
            [coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3])) for T in w] for w in worlds
        ]

    def _pose(self, k: int) -> None:
        for obj, tf in zip(self.objects, self.tf[k]):
            obj.setTransform(tf)

    def check(self, k: int) -> None:
        self._pose(k)
        for a, b in self.pairs:
            res = self.coal.CollisionResult()
            self.coal.collide(a, b, self.creq, res)
            if res.isCollision():
                _ = [(c.b1, c.b2) for c in res.getContacts()]

    def first_hit(self, k: int) -> None:
        self._pose(k)
        for a, b in self.pairs:
            self.coal.collide(a, b, self.creq1, self.coal.CollisionResult())

    def distance(self, k: int) -> None:
        self._pose(k)
        for a, b in self.pairs:
            res = self.coal.DistanceResult()
            self.coal.distance(a, b, self.dreq, res)
            _ = (res.getNearestPoint1(), res.getNearestPoint2())


class _Fcl(_Engine):
    name = "fcl"

    def __init__(self, model, worlds: np.ndarray, mode: np.ndarray) -> None:
        import fcl

        self.fcl = fcl
        self.objects = []
        for body in model.bodies:
            bvh = fcl.BVHModel()
            bvh.beginModel(len(body.mesh.faces), len(body.mesh.vertices))
            bvh.addSubModel(np.asarray(body.mesh.vertices, dtype=float), np.asarray(body.mesh.faces, dtype=np.int32))
            bvh.endModel()
            self.objects.append(fcl.CollisionObject(bvh, fcl.Transform()))
        self.pairs = [tuple(map(int, p)) for p, m in zip(model.pairs, mode) if m > 0]
        self.tf = [[fcl.Transform(T[:3, :3], T[:3, 3]) for T in w] for w in worlds]
        self.creq = fcl.CollisionRequest(num_max_contacts=100000, enable_contact=False)
        self.creq1 = fcl.CollisionRequest(num_max_contacts=1, enable_contact=False)
        self.dreq = fcl.DistanceRequest(enable_nearest_points=True)

    def _pose(self, k: int) -> None:
        for obj, tf in zip(self.objects, self.tf[k]):
            obj.setTransform(tf)

    def check(self, k: int) -> None:
        self._pose(k)
        for a, b in self.pairs:
            res = self.fcl.CollisionResult()
            if self.fcl.collide(self.objects[a], self.objects[b], self.creq, res):
                _ = [(c.b1, c.b2) for c in res.contacts]

    def first_hit(self, k: int) -> None:
        self._pose(k)
        for a, b in self.pairs:
            self.fcl.collide(self.objects[a], self.objects[b], self.creq1, self.fcl.CollisionResult())

    def distance(self, k: int) -> None:
        self._pose(k)
        for a, b in self.pairs:
            res = self.fcl.DistanceResult()
            self.fcl.distance(self.objects[a], self.objects[b], self.dreq, res)
            _ = res.nearest_points


@dataclass
class StreamResult:
    poses: int
    distance_poses: int
    colliding_poses: int
    check_us: dict[str, float] = field(default_factory=dict)
    first_hit_us: dict[str, float] = field(default_factory=dict)
    distance_us: dict[str, float] = field(default_factory=dict)


def _timed(engines: list[_Engine], what: str, n: int) -> dict[str, float]:
    """Mean microseconds per pose of ``what`` for each engine, interleaved in chunks."""
    total = {e.name: 0.0 for e in engines}
    for e in engines:
        if hasattr(e, "reset"):
            e.reset()
    for start in range(0, n, CHUNK):
        stop = min(start + CHUNK, n)
        for e in engines:
            fn = getattr(e, what)
            t0 = time.perf_counter()
            for k in range(start, stop):
                fn(k)
            total[e.name] += time.perf_counter() - t0
    return {k: v / n * 1e6 for k, v in total.items()}


def run(drag_poses: int = 10000, random_poses: int = 2000, distance_poses: int = 500, engines=("ours", "coal", "fcl"),
        seed: int = 1) -> dict:
    """Run both streams; return the figures (microseconds per pose) and ratios (theirs / ours)."""
    _reference_path()
    from shared.cells.loader import DEFAULT_CELL, load_cell
    from shared.collision import SceneModel

    cell = load_cell(DEFAULT_CELL)
    t0 = time.perf_counter()
    model = SceneModel.from_cell(cell)
    build_s = time.perf_counter() - t0
    model.check(cell.q_home)  # compile or load the numba cache
    mode = model._mode(model.new_data(), "none", (), frozenset())
    rng = np.random.default_rng(seed)
    streams = {
        "dragging": work_dragging(cell, drag_poses, rng),
        "random": rng.uniform(cell.robot.lower, cell.robot.upper, size=(random_poses, cell.robot.dof)),
    }
    out: dict = {
        "cell": str(DEFAULT_CELL.name),
        "bodies": len(model.bodies),
        "pairs_checked": int((mode > 0).sum()),
        "triangles": int(sum(len(b.mesh.faces) for b in model.bodies)),
        "model_build_s": round(build_s, 3),
        "machine": f"{platform.machine()}, Python {platform.python_version()}",
        "unit": "microseconds per pose",
        "streams": {},
    }
    for name, qs in streams.items():
        worlds = np.array([model._world_poses(q, None) for q in qs])
        engs: list[_Engine] = []
        for e in engines:
            if e == "ours":
                engs.append(_Ours(model, qs))
            elif e == "coal":
                engs.append(_Coal(model, worlds, mode))
            elif e == "fcl":
                engs.append(_Fcl(model, worlds, mode))
            else:
                raise ValueError(f"unknown engine {e!r}: ours, coal, fcl")
        data = model.new_data()
        colliding = sum(model.check(q, data=data, distances="none", triangles=False).colliding for q in qs)
        res = StreamResult(len(qs), min(distance_poses, len(qs)), int(colliding))
        res.check_us = _timed(engs, "check", len(qs))
        res.first_hit_us = _timed(engs, "first_hit", len(qs))
        res.distance_us = _timed(engs, "distance", res.distance_poses)
        doc = {
            "poses": res.poses,
            "colliding_poses": res.colliding_poses,
            "distance_poses": res.distance_poses,
            "check_us": {k: round(v, 1) for k, v in res.check_us.items()},
            "first_hit_us": {k: round(v, 1) for k, v in res.first_hit_us.items()},
            "distance_us": {k: round(v, 1) for k, v in res.distance_us.items()},
        }
        if "ours" in res.check_us:
            doc["checks_per_s_ours"] = round(1e6 / res.check_us["ours"], 1)
            doc["ratio_check"] = {k: round(v / res.check_us["ours"], 2) for k, v in res.check_us.items() if k != "ours"}
            doc["ratio_first_hit"] = {
                k: round(v / res.first_hit_us["ours"], 2) for k, v in res.first_hit_us.items() if k != "ours"
            }
            doc["ratio_distance"] = {
                k: round(v / res.distance_us["ours"], 2) for k, v in res.distance_us.items() if k != "ours"
            }
        out["streams"][name] = doc
    return out


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--drag-poses", type=int, default=10000, help="poses of the dragging motion (default 10000)")
    p.add_argument("--random-poses", type=int, default=2000, help="random poses (default 2000)")
    p.add_argument("--distance-poses", type=int, default=500,
                   help="poses of each stream used for the distance queries (default 500; they are slow)")
    p.add_argument("--engines", default="ours,coal,fcl", help="comma-separated: ours, coal, fcl")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--json", action="store_true")


def main_with(args: argparse.Namespace) -> int:
    for n in ("drag_poses", "random_poses", "distance_poses"):
        if getattr(args, n) < 1:
            from shared.errors import InputError

            raise InputError(f"--{n.replace('_', '-')} must be at least 1")
    engines = tuple(e.strip() for e in args.engines.split(",") if e.strip())
    for e in engines:
        if e not in ("ours", "coal", "fcl"):
            from shared.errors import UnknownNameError

            raise UnknownNameError("engine", e, ["ours", "coal", "fcl"])
    res = run(args.drag_poses, args.random_poses, args.distance_poses, engines, args.seed)
    if args.json:
        print(json.dumps(res))
        return 0
    print(f"{res['cell']}: {res['bodies']} bodies, {res['pairs_checked']} pairs checked, {res['triangles']} triangles; "
          f"model build {res['model_build_s']} s")
    for name, s in res["streams"].items():
        print(f"\n{name}: {s['poses']} poses ({s['colliding_poses']} colliding), microseconds per pose")
        print(f"  {'engine':8s} {'check':>10s} {'first hit':>10s} {'distance':>10s}")
        for e in s["check_us"]:
            print(f"  {e:8s} {s['check_us'][e]:10.1f} {s['first_hit_us'][e]:10.1f} {s['distance_us'][e]:10.1f}")
        if "ratio_check" in s:
            print(f"  ours: {s['checks_per_s_ours']:.0f} checks/s; theirs/ours: check {s['ratio_check']}, "
                  f"first hit {s['ratio_first_hit']}, distance {s['ratio_distance']} "
                  f"(distance on the first {s['distance_poses']} poses)")
    return 0


def main(argv=None, prog: str | None = None) -> int:
    p = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    add_arguments(p)
    return main_with(p.parse_args(argv))


if __name__ == "__main__":
    _reference_path()
    try:
        sys.exit(main())
    except Exception as exc:  # a TeleprogError from bad options: one line, as the CLI does
        from shared.errors import TeleprogError

        if not isinstance(exc, TeleprogError):
            raise
        print(f"bench_collision: error: {exc}", file=sys.stderr)
        sys.exit(1)
