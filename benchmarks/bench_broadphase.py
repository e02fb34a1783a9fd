"""Many-body collision detection (thesis chapter 5): the thesis's experiments and the libraries
people use today, on the same particle-sedimentation frames.

    .venv/bin/teleprog bench broadphase                 # tables and figure
    .venv/bin/python benchmarks/bench_broadphase.py --json
    .venv/bin/python benchmarks/bench_broadphase.py --experiments scale --max-n 100000

Experiments (FPS = detections per second of detection time only, as the thesis measures it):

* ``t51``: complexity in N (Table 5.1): density 0.0005, SPEED 0.5, N = 16 .. 2048;
* ``t52``: spatial coherence in L (Table 5.2): N = 256, SPEED 0.5, L = 16 .. 256;
* ``t53``: temporal coherence in SPEED (Table 5.3): N = 512, L = 100, SPEED 0.1 .. 12.8;
* ``scale``: uniform (density 0.0005) and clustered scenes (Gaussian clouds, a sediment layer;
  same N and cube) at N = 1,000 .. 1,000,000, with the peers: scipy's ``cKDTree.query_pairs``
  (tree rebuilt every frame, then the exact sphere test and sort), coal's
  ``DynamicAABBTreeCollisionManager`` and coal's ``SaPCollisionManager`` (FCL's
  sweep-and-prune, the I-COLLIDE family) with ``CollisionCallBackCollect``. For coal the time
  of ``update()`` + ``collide()`` counts; the Python loop that moves the objects is reported
  beside it but not counted (it favours coal).

Every frame all engines see the same centres, interleaved, so a machine shared with other jobs
slows them alike. Two figures per engine: ``fps`` = 1 / the median frame time (robust to another
job's burst; used for the thesis's tables), and ``fps_mean`` = frames / total time (the thesis's
definition; it counts every rebuild of ``usscd_skin`` in full, so the ratios against the peers
use it). The first two frames of each engine (JIT warm-up, first sort, partition fitting, first
skin list) are not timed; the first one's time is reported as ``first_frame_s``. Our methods'
answers are compared with each other on every timed frame, and cKDTree's with ours
(``frames_differing_from_ours``; coal's counts are box overlaps and are not compared).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

FIG_DIR = ROOT / "benchmarks" / "figures"
OURS = ("usscd", "usscd_skin", "scd", "icollide", "pbnuss", "cbass", "ugrid", "ugrid_skin")
SLOW = ("scd", "icollide")  # O(n log n + sweep) without subdivision: capped at --max-n-slow
PEERS = ("ckdtree", "coal_tree", "coal_sap")
THESIS = {
    "t51": {"n": [16, 32, 64, 128, 256, 512, 1024, 2048]},
    "t52": {"size": [16, 32, 64, 128, 256]},
    "t53": {"speed": [0.1, 0.2, 0.4, 0.8, 1.6, 3.2, 6.4, 12.8]},
}


@dataclass
class Row:
    experiment: str
    kind: str
    n: int
    size: float
    speed: float
    engine: str
    fps: float
    frames: int
    pairs: int
    extra: dict = field(default_factory=dict)


# ------------------------------------------------------------------------------------ peers


class CKDTreePeer:
    name = "ckdtree"

    def setup(self, centres, radii):
        pass

    def frame(self, centres, radii):
        from scipy.spatial import cKDTree

        t0 = time.perf_counter()
        cand = cKDTree(centres).query_pairs(2.0 * float(radii.max()), output_type="ndarray")
        i, j = cand[:, 0], cand[:, 1]
        d2 = ((centres[i] - centres[j]) ** 2).sum(axis=1)
        keep = d2 <= (radii[i] + radii[j]) ** 2
        key = np.sort(np.minimum(i, j)[keep] * len(centres) + np.maximum(i, j)[keep])
        pairs = np.stack([key // len(centres), key % len(centres)], axis=1)
        return time.perf_counter() - t0, pairs, 0.0


class CoalPeer:
    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.name = "coal_tree" if kind == "tree" else "coal_sap"

    def setup(self, centres, radii):
        import coal

        self.m = coal.DynamicAABBTreeCollisionManager() if self.kind == "tree" else coal.SaPCollisionManager()
        self.objs = []
        for c, r in zip(centres, radii):
            o = coal.CollisionObject(coal.Sphere(float(r)))
            o.setTranslation(c)
            o.computeAABB()
            self.objs.append(o)
            self.m.registerObject(o)
        self.m.setup()
        self.cap = 64

    def frame(self, centres, radii):
        import coal

        t0 = time.perf_counter()
        for o, c in zip(self.objs, centres):
            o.setTranslation(c)
            o.computeAABB()
        t1 = time.perf_counter()
        while True:
            cb = coal.CollisionCallBackCollect(self.cap)
            t2 = time.perf_counter()
            self.m.update()
            self.m.collide(cb)
            t3 = time.perf_counter()
            k = cb.numCollisionPairs()
            if k < self.cap:
                break
            self.cap *= 4
        return t3 - t2, k, t1 - t0


# ------------------------------------------------------------------------------------ runs


def frames_for(n: int, base: int) -> int:
    return int(np.clip(base * 20000 // max(n, 1), 10, base))


def run_config(exp, kind, n, size, speed, engines, peers, frames, seed, log) -> list[Row]:
    from shared.broadphase import make_detector
    from shared.broadphase.workloads import make_scene

    scene = make_scene(kind, n=n, size=size, speed=speed, seed=seed)
    dets = {e: make_detector(e) for e in engines}
    peer_objs = []
    setup_s: dict[str, float] = {}
    for p in peers:
        obj = CKDTreePeer() if p == "ckdtree" else CoalPeer("tree" if p == "coal_tree" else "sap")
        t = time.perf_counter()
        obj.setup(scene.centres, scene.radii)
        setup_s[p] = time.perf_counter() - t
        peer_objs.append(obj)
    spent = {e: [] for e in list(engines) + list(peers)}
    moving = {p: 0.0 for p in peers}
    counts: dict[str, int] = {}
    mismatch: dict[str, int] = {}
    for warm in range(2):  # untimed: compilation, first sort, partition fitting, first list
        for e, d in dets.items():
            t = time.perf_counter()
            d.update(scene.centres, scene.radii)
            if warm == 0:
                setup_s[e] = time.perf_counter() - t
        for obj in peer_objs:
            obj.frame(scene.centres, scene.radii)
        scene.step()
    for f in range(frames):
        scene.step()
        ref = None
        for e, d in dets.items():
            t = time.perf_counter()
            pairs = d.update(scene.centres, scene.radii)
            spent[e].append(time.perf_counter() - t)
            counts[e] = len(pairs)
            if ref is None:
                ref = pairs
            elif not np.array_equal(pairs, ref):
                mismatch[e] = mismatch.get(e, 0) + 1
        for obj in peer_objs:
            dt, got, move = obj.frame(scene.centres, scene.radii)
            spent[obj.name].append(dt)
            moving[obj.name] += move
            if isinstance(got, int):  # coal's collect callback counts box overlaps only
                counts[obj.name] = got
            else:
                counts[obj.name] = len(got)
                if ref is not None and not np.array_equal(got, ref):
                    mismatch[obj.name] = mismatch.get(obj.name, 0) + 1
    rows = []
    for e in spent:
        extra = {"first_frame_s": round(setup_s.get(e, 0.0), 4)}
        if e in moving:
            extra["python_move_fps"] = round(frames / moving[e], 3) if moving[e] else None
            extra["pairs_are"] = "box overlaps (coal's collect callback runs no sphere test)"
        if mismatch.get(e):
            extra["frames_differing_from_ours"] = mismatch[e]
        times = np.asarray(spent[e])
        extra["fps_mean"] = round(float(len(times) / times.sum()), 3)
        rows.append(Row(exp, kind, n, round(scene.size, 3), speed, e, float(1.0 / np.median(times)),
                        frames, counts.get(e, 0), extra))
    for r in rows:
        log(f"  {exp:8s} {kind:8s} N={n:>8d} L={r.size:>8.1f} SPEED={speed:<5} {r.engine:10s} "
            f"{r.fps:12.2f} FPS (median) {r.extra['fps_mean']:12.2f} (mean)  pairs {r.pairs}")
    return rows


def run(args, log) -> list[Row]:
    exps = [e.strip() for e in args.experiments.split(",") if e.strip()]
    rows: list[Row] = []
    fast = [m for m in OURS]
    if "t51" in exps:
        for n in THESIS["t51"]["n"]:
            rows += run_config("t51", "uniform", n, None, 0.5, fast, [], args.frames, args.seed, log)
    if "t52" in exps:
        for size in THESIS["t52"]["size"]:
            rows += run_config("t52", "uniform", 256, float(size), 0.5, fast, [], args.frames, args.seed, log)
    if "t53" in exps:
        for sp in THESIS["t53"]["speed"]:
            rows += run_config("t53", "uniform", 512, 100.0, sp, fast, [], args.frames, args.seed, log)
    if "scale" in exps:
        for kind in [k.strip() for k in args.kinds.split(",") if k.strip()]:
            for n in [int(x) for x in args.sizes.split(",")]:
                if n > args.max_n:
                    continue
                engines = [m for m in OURS if m not in SLOW or n <= args.max_n_slow]
                peers = [p for p in args.peers.split(",") if p and (p == "ckdtree" or n <= args.coal_max_n)]
                peers = [p for p in peers if p != "coal_sap" or n <= args.coal_sap_max_n]
                rows += run_config("scale", kind, n, None, 0.5, engines, peers,
                                   frames_for(n, args.frames), args.seed, log)
    return rows


def ratios(rows: list[Row]) -> list[dict]:
    """Per scale configuration: our fastest method against the fastest peer, on the mean FPS
    (frames over total time: rebuild frames of ``usscd_skin`` count in full)."""
    out = []
    keys = sorted({(r.kind, r.n) for r in rows if r.experiment == "scale"})
    for kind, n in keys:
        sel = [r for r in rows if r.experiment == "scale" and r.kind == kind and r.n == n]
        ours = [r for r in sel if r.engine in OURS]
        peers = [r for r in sel if r.engine in PEERS]
        if not ours or not peers:
            continue
        best = max(ours, key=lambda r: r.extra["fps_mean"])
        peer = max(peers, key=lambda r: r.extra["fps_mean"])
        out.append({"kind": kind, "n": n, "ours": best.engine, "ours_fps": best.extra["fps_mean"],
                    "peer": peer.engine, "peer_fps": peer.extra["fps_mean"],
                    "ratio": round(best.extra["fps_mean"] / peer.extra["fps_mean"], 1)})
    return out


def plot(rows: list[Row], path: Path) -> None:
    """Three panels for the thesis's tables, three for the scale runs (one per scene kind)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(17, 10))
    panels = [("t51", "n", "N (density 0.0005, SPEED 0.5)", "Table 5.1: complexity"),
              ("t52", "size", "L (N 256, SPEED 0.5)", "Table 5.2: spatial coherence"),
              ("t53", "speed", "SPEED (N 512, L 100)", "Table 5.3: temporal coherence")]
    for ax, (exp, key, label, title) in zip(axes[0], panels):
        for i, e in enumerate(OURS):
            sel = sorted((getattr(r, key), r.fps) for r in rows if r.experiment == exp and r.engine == e)
            if sel:
                ax.plot(*zip(*sel), marker="o", color=f"C{i}", label=e)
        ax.set(xscale="log", yscale="log", xlabel=label, ylabel="FPS (1 / median frame time)", title=title)
        ax.grid(True, which="both", alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=8)
    for ax, kind in zip(axes[1], ("uniform", "gaussian", "sediment")):
        for i, e in enumerate(list(OURS) + list(PEERS)):
            sel = sorted((r.n, r.extra["fps_mean"]) for r in rows
                         if r.experiment == "scale" and r.kind == kind and r.engine == e)
            if sel:
                ax.plot(*zip(*sel), marker="o" if e in OURS else "s", ls="-" if e in OURS else "--",
                        color=f"C{i}", label=e)
        ax.set(xscale="log", yscale="log", xlabel=f"N ({kind}, density 0.0005, SPEED 0.5)", ylabel="FPS (mean)",
               title=f"Scale and peers: {kind}")
        ax.grid(True, which="both", alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--experiments", default="t51,t52,t53,scale", help="comma list of t51,t52,t53,scale")
    p.add_argument("--sizes", default="1000,10000,100000,1000000", help="N of the scale experiment")
    p.add_argument("--kinds", default="uniform,gaussian,sediment", help="scenes of the scale experiment")
    p.add_argument("--max-n", type=int, default=1_000_000, help="skip scale sizes above this")
    p.add_argument("--max-n-slow", type=int, default=100_000, help="largest N for scd and icollide")
    p.add_argument("--peers", default="ckdtree,coal_tree,coal_sap", help="comma list of " + ",".join(PEERS))
    p.add_argument("--coal-max-n", type=int, default=1_000_000, help="largest N for coal (1M: ~1 GB, ~10 s set-up)")
    p.add_argument("--coal-sap-max-n", type=int, default=10_000, help="largest N for coal's SaP manager")
    p.add_argument("--frames", type=int, default=30, help="timed frames per configuration (fewer at large N)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--threading-layer", default="workqueue",
                   help="numba threading layer (default workqueue: OpenMP's spinning collapses on a busy machine)")
    p.add_argument("--plot", default=str(FIG_DIR / "broadphase_experiments.png"), help="figure path ('' for none)")
    p.add_argument("--json", action="store_true")


def _layer(numba) -> str | None:
    try:
        return numba.threading_layer()
    except ValueError:  # no parallel kernel ran (small scenes use serial ones)
        return None


def main_with(args: argparse.Namespace) -> int:
    from shared.errors import InputError

    if args.frames < 1:
        raise InputError("--frames must be at least 1")
    for p in [x for x in args.peers.split(",") if x]:
        if p not in PEERS:
            raise InputError(f"unknown peer {p!r}; valid: {', '.join(PEERS)}")
    import numba

    if args.threading_layer:
        numba.config.THREADING_LAYER = args.threading_layer  # only effective before the first parallel call
    log = (lambda s: print(s, file=sys.stderr, flush=True)) if args.json else (lambda s: print(s, flush=True))
    t0 = time.time()
    rows = run(args, log)
    result = {
        "machine": f"{platform.machine()}, {numba.config.NUMBA_NUM_THREADS} threads, Python {platform.python_version()}",
        "threading_layer": _layer(numba),
        "seconds": round(time.time() - t0, 1),
        "rows": [asdict(r) for r in rows],
        "ratios": ratios(rows),
    }
    if args.plot and rows:
        plot(rows, Path(args.plot))
        result["plot"] = args.plot
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print("\nfastest of ours vs fastest peer (scale experiment):")
        for r in result["ratios"]:
            print(f"  {r['kind']:8s} N={r['n']:>8d}  {r['ours']} {r['ours_fps']:.1f} FPS vs {r['peer']} "
                  f"{r['peer_fps']:.2f} FPS  ->  {r['ratio']}x")
        if args.plot and rows:
            print(f"figure: {args.plot}")
    return 0


def main(argv=None, prog: str | None = None) -> int:
    p = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    add_arguments(p)
    return main_with(p.parse_args(argv))


if __name__ == "__main__":
    try:
        sys.exit(main())
    except Exception as exc:  # noqa: BLE001 - one line for a person, not a traceback
        from shared.errors import TeleprogError

        if isinstance(exc, TeleprogError):
            print(f"error: {exc}", file=sys.stderr)
            sys.exit(1)
        raise
