"""Threads for the collision checks (issue 35): the sequential path against two threads on the same work.

    .venv/bin/python benchmarks/bench_collision_threads.py            # table (about 30 s)
    .venv/bin/python benchmarks/bench_collision_threads.py --quick    # a few hundred poses (about 7 s)
    teleprog bench collision_threads --json

Seed 002 pipelines its collision stages on threads and reports a 13-20 % gain. Our checks are
compiled numba kernels; a kernel compiled with ``nogil=True`` drops the GIL while it runs, so two
of them can run at once on two cores. What is measured, per check, wall time (the threaded
paths' time is wall time by nature), sequential and threaded interleaved pose by pose (one
pose sequential then threaded, the next the other way round), the same poses, the results
asserted equal (bit for bit):

* ``headroom``: the control. A compute-only nogil kernel of about 0.5 ms, once on one thread
  and split in halves over two: a free second core gives about 2x. Below that the other core
  was busy (other jobs; in the console, its event loop, the robot-io loop, the page's clients).
  ``handoff``: one empty ``ThreadPoolExecutor.submit(...).result()`` round trip, and
  ``event_round_trip`` a bare ``threading.Event`` ping-pong with a thread that had fallen
  asleep (what waking the other core costs, the executor aside). Measured before and after.
* ``scene_distance``: the peg-in-hole cell's full distance query (``SceneModel`` with
  ``distances="all"``: 34 body pairs, GJK on convex pieces), as ``benchmarks/bench_collision.py``
  drives it on its dragging and random streams. Threaded: the pairs split in two halves of equal
  measured cost, each half one ``kernels.check_packed`` call (nogil) with its own ``SceneData``
  (the pairs' coherence state is per pair, so each half's state evolves as the whole one's).
  ``random_batch``: the parallel ceiling without a hand-off per check: runs of 50 random poses,
  the first half on this thread, the second on the worker. The collision-only check (14-26 us a pose) is shorter than the hand-off itself and is not tried.
* ``terrain_contact``: the work of ``GroundChecker.contact`` on the rover-terrain cell
  (``assets/cells/rover_terrain.toml``, about 20,000 triangles): the arm's exact distance
  (one group), the head's and the rest's (two groups), the 252 sensor rays, and the touching
  triangles on contact; poses as ``benchmarks/bench_terrain.py`` draws them (half random, half
  with point C 0-60 mm above the ground). Threaded ``overlap``: the rays run on the worker
  while this thread runs both distance queries; ``split_rays``: the rays in two halves, one per
  thread. The terrain queries (``shared.terrain.tree``) are compiled without ``nogil``; the
  benchmark wraps them in ``nogil=True`` kernels (same code, same results) for both paths.
* ``terrain_batch``: many poses at once, as instrument placement checks its approach paths
  (12 samples a path, ``placement.PATH_SAMPLES``): per pose the shapes' poses (pinocchio, in
  Python, under the GIL) and the two-group distance. Threaded ``halves``: each thread takes half
  the batch; ``pipeline``: this thread places pose i + 1 while the worker queries pose i.

Ratio = sequential / threaded (above 1: the threads are faster).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from datetime import datetime, timezone
from pathlib import Path

import numba
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
for _p in (str(ROOT), str(ROOT / "benchmarks")):
    if _p not in sys.path:
        sys.path.insert(0, _p)

from shared.terrain.tree import query_shapes, ray_hits  # noqa: E402

#: a threaded path "pays" when its p50 is this much faster than the sequential one
PAYS = 1.10
#: poses per batch in ``terrain_batch`` (placement checks 12 samples along each approach path)
BATCH = 12
#: poses per batch in ``scene_distance.random_batch`` (the parallel ceiling: one hand-off a batch)
SCENE_BATCH = 50


# -- nogil kernels ------------------------------------------------------------------------------
# Thin nogil entries around the terrain kernels: numba compiles the callee into each, so the
# work is the library's own, and the wrappers are the only difference. Both paths call them.


@numba.njit(cache=True, nogil=True)
def query_shapes_nogil(kinds, Rs, ts, pars, groups, n_groups, vertices, faces, lo, hi, starts, counts, branching,
                       leaf_size, cap, out_d, out_pa, out_pb, out_pos, out_shape):
    return query_shapes(kinds, Rs, ts, pars, groups, n_groups, vertices, faces, lo, hi, starts, counts, branching,
                        leaf_size, cap, out_d, out_pa, out_pb, out_pos, out_shape)


@numba.njit(cache=True, nogil=True)
def ray_hits_nogil(origins, dirs, tmax, vertices, faces, lo, hi, starts, counts, branching, leaf_size, out_t, out_pos):
    ray_hits(origins, dirs, tmax, vertices, faces, lo, hi, starts, counts, branching, leaf_size, out_t, out_pos)


@numba.njit(cache=True, nogil=True)
def spin(n):
    """Compute only (no memory traffic): the control for how much a second thread can add."""
    s = 0.0
    for i in range(n):
        s += np.sqrt(i * 1.0 + s * 1e-9)
    return s


def _kernels():
    """This file imported under its own name, whose kernels the benchmark calls. numba's cache
    records the module that defines a kernel by name, and this file runs as ``__main__`` or as
    ``teleprog bench``'s module: a cache written one way would not load the other way. The
    kernels are therefore always compiled in the module ``bench_collision_threads``
    (``benchmarks/`` is on the path, above)."""
    import bench_collision_threads

    return bench_collision_threads


# -- measurement helpers ------------------------------------------------------------------------


def _stats(ns) -> dict:
    a = np.asarray(ns, dtype=float) / 1e3  # us
    return {"p50_us": round(float(np.median(a)), 1), "p95_us": round(float(np.percentile(a, 95)), 1),
            "mean_us": round(float(a.mean()), 1)}


def _compare(seq: list[int], thr: list[int]) -> dict:
    s, t = _stats(seq), _stats(thr)
    r50 = s["p50_us"] / t["p50_us"]
    return {"sequential": s, "threaded": t, "ratio_p50": round(r50, 3),
            "ratio_p95": round(s["p95_us"] / t["p95_us"], 3), "pays": bool(r50 > PAYS)}


def _bar(n: int, desc: str):
    from tqdm import tqdm

    return tqdm(total=n, desc=desc, unit="pose", file=sys.stderr, disable=None, leave=False)


def _interleaved(n: int, seq, variants: dict, desc: str, check) -> dict:
    """Time ``seq(k)`` and each ``variants[name](k)`` for k < n, alternating which goes first;
    ``check(k, a, b)`` asserts a variant's answer equals the sequential one."""
    t_seq: list[int] = []
    t_var: dict[str, list[int]] = {name: [] for name in variants}
    bar = _bar(n, desc)
    for k in range(n):
        calls = [("seq", seq), *variants.items()]
        if k % 2:
            calls.reverse()
        out = {}
        for name, fn in calls:
            t0 = time.perf_counter_ns()
            out[name] = fn(k)
            dt = time.perf_counter_ns() - t0
            (t_seq if name == "seq" else t_var[name]).append(dt)
        for name in variants:
            check(k, out["seq"], out[name])
        bar.update(1)
    bar.close()
    return {name: _compare(t_seq, t) for name, t in t_var.items()}


def headroom(pool: ThreadPoolExecutor, reps: int) -> dict:
    """The control: a 0.5 ms compute kernel on one thread against its halves on two."""
    spin = _kernels().spin
    n = 400_000
    spin(10)
    t0 = time.perf_counter_ns()
    spin(n)
    scale = 500_000 / max(time.perf_counter_ns() - t0, 1)
    n = max(int(n * scale), 10_000)  # about 0.5 ms here and now
    seq, thr, hand, wake = [], [], [], []
    go, back = threading.Event(), threading.Event()
    done = False

    def echo():
        while True:
            go.wait()
            go.clear()
            back.set()
            if done:
                return

    echoer = threading.Thread(target=echo, daemon=True, name="bench-threads-echo")
    echoer.start()
    for k in range(reps):
        for order in ((0, 1) if k % 2 == 0 else (1, 0)):
            t0 = time.perf_counter_ns()
            if order == 0:
                spin(n)
                seq.append(time.perf_counter_ns() - t0)
            else:
                f = pool.submit(spin, n // 2)
                spin(n - n // 2)
                f.result()
                thr.append(time.perf_counter_ns() - t0)
        t0 = time.perf_counter_ns()
        pool.submit(int).result()
        hand.append(time.perf_counter_ns() - t0)
        spin(n // 4)  # let both threads fall asleep again, as between two checks
        t0 = time.perf_counter_ns()
        go.set()
        back.wait()
        back.clear()
        wake.append(time.perf_counter_ns() - t0)
    done = True
    go.set()
    echoer.join(1.0)
    return {"spin": _compare(seq, thr), "handoff": _stats(hand), "event_round_trip": _stats(wake)}


# -- the peg-in-hole scene: distances of all pairs ------------------------------------------------


def scene_distance(pool: ThreadPoolExecutor, n_drag: int, n_random: int, seed: int) -> dict:
    from bench_collision import work_dragging

    from shared.cells.loader import DEFAULT_CELL, load_cell
    from shared.collision import SceneModel

    cell = load_cell(DEFAULT_CELL)
    model = SceneModel.from_cell(cell)
    model.check(cell.q_home)
    tpl = model._template_poses
    mode = model._mode(model.new_data(), "all", (), frozenset())
    n_p = len(mode)

    # split the pairs in two halves of equal cost, measured pair by pair on other poses
    rng = np.random.default_rng(seed + 1)
    calib = rng.uniform(cell.robot.lower, cell.robot.upper, (100, cell.robot.dof))
    cost = np.zeros(n_p)
    for p in np.flatnonzero(mode):
        m = np.zeros(n_p, np.int8)
        m[p] = mode[p]
        m.flags.writeable = False
        d = model.new_data()
        t0 = time.perf_counter_ns()
        for q in calib:
            model._run(tpl, m, d, True, q)
        cost[p] = time.perf_counter_ns() - t0
    side = np.zeros(n_p, np.int64)
    load = [0.0, 0.0]
    for p in np.argsort(-cost):
        s = int(load[1] < load[0])
        side[p] = s
        load[s] += cost[p]
    halves = []
    for s in (0, 1):
        m = mode.copy()
        m[side != s] = 0
        m.flags.writeable = False
        halves.append(m)
    mA, mB = halves
    in_a = (mA > 0)[:, None]
    asked = mode > 0

    rng = np.random.default_rng(seed)
    streams = {
        "dragging": work_dragging(cell, n_drag, rng),
        "random": rng.uniform(cell.robot.lower, cell.robot.upper, (n_random, cell.robot.dof)),
    }
    out: dict = {"cell": DEFAULT_CELL.name, "pairs": int(asked.sum()),
                 "split_cost_share": round(load[0] / (load[0] + load[1]), 3)}
    for name, qs in streams.items():
        ds, da, db = model.new_data(), model.new_data(), model.new_data()

        def seq(k, qs=qs, ds=ds):
            hit, res, _ = model._run(tpl, mode, ds, True, qs[k])
            return hit, res

        def split(k, qs=qs, da=da, db=db):
            f = pool.submit(model._run, tpl, mB, db, True, qs[k])
            ha, ra, _ = model._run(tpl, mA, da, True, qs[k])
            hb, rb, _ = f.result()
            return ha | hb, np.where(in_a, ra, rb)

        def check(k, a, b):
            assert np.array_equal(a[0], b[0]), f"pose {k}: interfering pairs differ"
            assert np.array_equal(a[1][asked], b[1][asked], equal_nan=True), f"pose {k}: distances differ"

        res = _interleaved(len(qs), seq, {"split_pairs": split}, f"scene {name}", check)
        res["poses"] = len(qs)
        out[name] = res

    # the ceiling without a hand-off per check: runs of SCENE_BATCH random poses, half on each
    # thread (independent poses: each half's coherence state starts where its thread left it)
    qs = streams["random"]
    batches = [qs[b:b + SCENE_BATCH] for b in range(0, len(qs) - SCENE_BATCH + 1, SCENE_BATCH)]
    ds, da, db = model.new_data(), model.new_data(), model.new_data()

    def run_poses(sub, d):
        return [model._run(tpl, mode, d, True, q)[1][:, 0].copy() for q in sub]

    def batch_seq(k):
        return run_poses(batches[k], ds)

    def batch_halves(k):
        h = SCENE_BATCH // 2
        f = pool.submit(run_poses, batches[k][h:], db)
        return run_poses(batches[k][:h], da) + f.result()

    def check_batch(k, a, b):
        assert all(np.array_equal(x[asked], y[asked], equal_nan=True) for x, y in zip(a, b)), f"batch {k}: distances differ"

    res = _interleaved(len(batches), batch_seq, {"halves": batch_halves}, "scene batches", check_batch)
    for v in res.values():  # per check, not per batch
        for side in ("sequential", "threaded"):
            v[side] = {k: round(x / SCENE_BATCH, 1) for k, x in v[side].items()}
    res["batches"] = len(batches)
    res["batch_size"] = SCENE_BATCH
    out["random_batch"] = res
    return out


# -- the rover cell's terrain --------------------------------------------------------------------


class _Terrain:
    """``GroundChecker.contact``'s kernel work on the nogil wrappers, sequential or threaded."""

    def __init__(self, terrain, pool: ThreadPoolExecutor) -> None:
        from shared.terrain.checks import SENSOR_RANGE

        self.checker = terrain.checker
        self.arm = self.checker.arm
        self.wTb = self.checker.world_T_base
        self.arrays = self.checker._arrays
        self.pool = pool
        self.k = _kernels()
        self.range = float(SENSOR_RANGE)
        n = len(self.arm.shapes)
        self.g_all = np.zeros(n, np.int64)
        self.g_head = np.zeros(n, np.int64)
        self.g_head[self.arm.tool_shape] = 1

    def query(self, Rs, ts, groups, n):
        out = (np.empty(n), np.zeros((n, 3)), np.zeros((n, 3)), np.empty(n, np.int64), np.empty(n, np.int64))
        self.k.query_shapes_nogil(self.arm.kinds, Rs, ts, self.arm.pars, groups, n, *self.arrays, np.inf, *out)
        return out

    def rays(self, A, dirs, t, pos):
        self.k.ray_hits_nogil(A, dirs, self.range, *self.arrays, t, pos)

    def prepare(self, q):
        Rs, ts = self.arm.shape_poses(self.wTb, q)
        A, B, _ = self.arm.sensors(self.wTb, q)
        seg = B - A
        d_S = np.linalg.norm(seg, axis=1)
        return Rs, ts, np.ascontiguousarray(A), np.ascontiguousarray(seg / d_S[:, None])

    def finish(self, Rs, ts, exact, head, t, pos):
        tris = np.zeros(0, np.int64)
        if exact[0][0] <= 0.0:
            tris = self.checker.triangles_near_shapes(Rs, ts, self.arm.kinds, self.arm.pars, 0.0)
        return exact, head, t, pos, tris

    def contact_seq(self, q):
        Rs, ts, A, dirs = self.prepare(q)
        t = np.empty(len(A))
        pos = np.empty(len(A), np.int64)
        self.rays(A, dirs, t, pos)
        exact = self.query(Rs, ts, self.g_all, 1)
        head = self.query(Rs, ts, self.g_head, 2)
        return self.finish(Rs, ts, exact, head, t, pos)

    def contact_overlap(self, q):
        Rs, ts, A, dirs = self.prepare(q)
        t = np.empty(len(A))
        pos = np.empty(len(A), np.int64)
        f = self.pool.submit(self.rays, A, dirs, t, pos)
        exact = self.query(Rs, ts, self.g_all, 1)
        head = self.query(Rs, ts, self.g_head, 2)
        f.result()
        return self.finish(Rs, ts, exact, head, t, pos)

    def contact_split_rays(self, q):
        Rs, ts, A, dirs = self.prepare(q)
        t = np.empty(len(A))
        pos = np.empty(len(A), np.int64)
        h = len(A) // 2
        f = self.pool.submit(self.rays, A[h:], dirs[h:], t[h:], pos[h:])
        self.rays(A[:h], dirs[:h], t[:h], pos[:h])
        f.result()
        exact = self.query(Rs, ts, self.g_all, 1)
        head = self.query(Rs, ts, self.g_head, 2)
        return self.finish(Rs, ts, exact, head, t, pos)

    # a batch of poses: per pose the shapes placed (Python) and the two-group distance
    def _one(self, q):
        Rs, ts = self.arm.shape_poses(self.wTb, q)
        return self.query(Rs, ts, self.g_head, 2)

    def batch_seq(self, qs):
        return [self._one(q) for q in qs]

    def batch_halves(self, qs):
        h = len(qs) // 2
        f = self.pool.submit(self.batch_seq, qs[h:])
        first = self.batch_seq(qs[:h])
        return first + f.result()

    def batch_pipeline(self, qs):
        out = []
        f = None
        for q in qs:
            Rs, ts = self.arm.shape_poses(self.wTb, q)
            if f is not None:
                out.append(f.result())
            f = self.pool.submit(self.query, Rs, ts, self.g_head, 2)
        out.append(f.result())
        return out


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
    return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))


def terrain(pool: ThreadPoolExecutor, n_poses: int, n_batches: int, seed: int) -> dict:
    from bench_terrain import _poses

    from shared.cells.loader import load_cell
    from shared.terrain.cell import load_cell_terrain

    cell = load_cell(ROOT / "assets" / "cells" / "rover_terrain.toml")
    ct = load_cell_terrain(cell)
    work = _Terrain(ct, pool)
    work.contact_seq(cell.q_home)  # compile or load numba's cache
    poses = _poses(ct.checker, n_poses, seed)
    contacts = sum(float(work.query(*work.arm.shape_poses(work.wTb, q), work.g_all, 1)[0][0]) <= 0.0 for q in poses[:n_poses])

    def check(k, a, b):
        assert _same(a, b), f"pose {k}: threaded and sequential answers differ"

    out: dict = {"cell": cell.name, "triangles": int(ct.tree.n_triangles), "rays": int(len(work.prepare(cell.q_home)[2])),
                 "poses": n_poses, "contact_poses": int(contacts)}
    out["contact"] = _interleaved(
        n_poses, lambda k: work.contact_seq(poses[k]),
        {"overlap": lambda k: work.contact_overlap(poses[k]), "split_rays": lambda k: work.contact_split_rays(poses[k])},
        "terrain contact", check)
    # batches of poses drawn from the same set; per-check time = batch time / BATCH
    rng = np.random.default_rng(seed + 2)
    batches = [poses[rng.choice(len(poses), BATCH, replace=False)] for _ in range(n_batches)]
    res = _interleaved(len(batches), lambda k: work.batch_seq(batches[k]),
                       {"halves": lambda k: work.batch_halves(batches[k]),
                        "pipeline": lambda k: work.batch_pipeline(batches[k])}, "terrain batch", check)
    for v in res.values():  # per check, not per batch
        for side in ("sequential", "threaded"):
            v[side] = {k: round(x / BATCH, 1) for k, x in v[side].items()}
    res["batches"] = len(batches)
    res["batch_size"] = BATCH
    out["batch"] = res
    return out


def run(quick: bool, seed: int) -> dict:
    load0 = os.getloadavg()
    started = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="bench-threads")  # + this thread = 2
    try:
        out = {"date": started, "cpus": os.cpu_count(), "load_before": [round(x, 2) for x in load0],
               "numba": numba.__version__, "python": sys.version.split()[0]}
        out["headroom"] = headroom(pool, 100 if quick else 400)
        n = (300, 200) if quick else (2000, 1000)
        out["scene_distance"] = scene_distance(pool, n[0], n[1], seed)
        out["terrain"] = terrain(pool, 200 if quick else 1000, 40 if quick else 300, seed)
        out["headroom_after"] = headroom(pool, 100 if quick else 400)
    finally:
        pool.shutdown()
    out["load_after"] = [round(x, 2) for x in os.getloadavg()]
    return out


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true", help="a few hundred poses (about 15 s)")
    p.add_argument("--seed", type=int, default=4)
    p.add_argument("--json", action="store_true")


def _row(label: str, r: dict) -> str:
    s, t = r["sequential"], r["threaded"]
    return (f"  {label:32s} {s['p50_us']:9.1f} {s['p95_us']:9.1f} {t['p50_us']:9.1f} {t['p95_us']:9.1f} "
            f"{r['ratio_p50']:6.2f}x {r['ratio_p95']:6.2f}x {'pays' if r['pays'] else ''}")


def main_with(args: argparse.Namespace) -> int:
    res = run(args.quick, args.seed)
    if args.json:
        print(json.dumps(res))
        return 0
    print(f"{res['date']}, {res['cpus']} CPUs, load {res['load_before']} -> {res['load_after']}")
    h0, h1 = res["headroom"], res["headroom_after"]
    print(f"control: 0.5 ms nogil kernel on two threads {h0['spin']['ratio_p50']:.2f}x / {h1['spin']['ratio_p50']:.2f}x "
          f"(before / after; 2x = a free second core); hand-off {h0['handoff']['p50_us']:.1f} us p50 "
          f"(a bare threading.Event round trip {h0['event_round_trip']['p50_us']:.1f} us)")
    print(f"  {'per check, wall (us)':32s} {'seq p50':>9s} {'seq p95':>9s} {'thr p50':>9s} {'thr p95':>9s} "
          f"{'p50':>7s} {'p95':>7s}")
    sd = res["scene_distance"]
    for stream in ("dragging", "random"):
        print(_row(f"scene distance {stream}, split", sd[stream]["split_pairs"]))
    print(_row(f"scene distance, {SCENE_BATCH} poses halves", sd["random_batch"]["halves"]))
    te = res["terrain"]
    for name, r in te["contact"].items():
        print(_row(f"terrain contact, {name}", r))
    for name in ("halves", "pipeline"):
        print(_row(f"terrain batch of {BATCH}, {name}", te["batch"][name]))
    print(f"scene: {sd['pairs']} pairs ({sd['split_cost_share']:.2f} of the cost in the first half); terrain: "
          f"{te['triangles']} triangles, {te['rays']} rays, {te['contact_poses']} of {te['poses']} poses in contact")
    return 0


def main(argv=None, prog: str | None = None) -> int:
    p = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    add_arguments(p)
    return main_with(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
