"""Time full scene checks of the collision core against coal on the same triangles and poses.

    .venv/bin/python tests/collision/bench_scene.py [--poses 2000] [--skip-wrist]

Two pose streams in the peg-in-hole cell: random joint vectors, and a dragging motion (small
consecutive steps between random waypoints, as the operator's gizmo produces). Per stream:
collision only (every interfering triangle pair / first hit) and collision + every pair's
distance. coal is called pair by pair on the same pairs (BVHModelOBBRSS of the same meshes).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "collision"))
from coal_reference import CoalScene, dragging_path  # noqa: E402

from shared.cells.loader import DEFAULT_CELL, load_cell  # noqa: E402
from shared.collision import SceneModel  # noqa: E402


def run(model: SceneModel, cs: CoalScene, qs: np.ndarray, skip) -> dict[str, float]:
    data = model.new_data()
    mode_c = model._mode(data, "none", skip, frozenset())
    mode_d = model._mode(data, "all", skip, frozenset())
    worlds = [model._world_poses(q, None) for q in qs]
    res = {}
    for label, kwargs in (
        ("collide_all_tris", dict(distances="none", triangles=True)),
        ("collide_first_hit", dict(distances="none", triangles=False)),
        ("collide_and_distances", dict(distances="all", triangles=True)),
    ):
        data.reset()
        t0 = time.perf_counter()
        for q in qs:
            model.check(q, data=data, skip=skip, **kwargs)
        res["ours " + label] = (time.perf_counter() - t0) / len(qs) * 1e6
    # the same without the Python report building and FK: kernel only on precomputed poses
    data.reset()
    t0 = time.perf_counter()
    for w in worlds:
        model._run(w, mode_d, data)
    res["ours kernel collide_and_distances"] = (time.perf_counter() - t0) / len(qs) * 1e6
    t0 = time.perf_counter()
    for q in qs:
        model._world_poses(q, None, data)
    res["fk + poses (shared by both)"] = (time.perf_counter() - t0) / len(qs) * 1e6
    for label, fn in (
        ("collide_all_tris", lambda: cs.collide(mode_c, True)),
        ("collide_first_hit", lambda: cs.collide(mode_c, False)),
        ("collide_and_distances", lambda: (cs.collide(mode_c, True), cs.distances(mode_d))),
    ):
        t0 = time.perf_counter()
        for w in worlds:
            cs.set_poses(w)
            fn()
        res["coal " + label] = (time.perf_counter() - t0) / len(qs) * 1e6
    return res


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--poses", type=int, default=2000)
    ap.add_argument("--skip-wrist", action="store_true", help="leave out link3/link6 and link4/link6 (always touching)")
    args = ap.parse_args()
    cell = load_cell(DEFAULT_CELL)
    t0 = time.perf_counter()
    model = SceneModel.from_cell(cell)
    print(f"model build {time.perf_counter() - t0:.2f} s, {len(model.bodies)} bodies, {len(model.pair_names)} pairs, "
          f"{sum(len(b.mesh.faces) for b in model.bodies)} triangles")
    cs = CoalScene(model)
    skip = (("link3", "link6"), ("link4", "link6")) if args.skip_wrist else ()
    model.check(cell.q_home)  # compile / load the cache
    rng = np.random.default_rng(1)
    streams = {
        "random": rng.uniform(cell.robot.lower, cell.robot.upper, size=(args.poses, cell.robot.dof)),
        "dragging": dragging_path(cell.robot, args.poses, rng),
    }
    for name, qs in streams.items():
        res = run(model, cs, qs, skip)
        print(f"\n{name} poses ({len(qs)}), microseconds per full scene check:")
        for k, v in res.items():
            print(f"  {k:40s} {v:9.1f}")


if __name__ == "__main__":
    main()
