"""CBASS (thesis §5.3.4): clustering-based adaptive subdivision.

HDBC clusters the centres (a seeded sample of at most ``sample`` of them); each cluster is
replaced by the axis-aligned box of its members; all box faces become split planes, so the
space between and around the boxes is cut at the boxes' coordinates (thesis fig. 5.8). A
region of that rectilinear partition belongs to the first (densest) cluster whose box holds its
centre - overlaps go to the denser cluster, case i) of fig. 5.7 - or to the background. Every
region gets the cell side of its owner's density (owner's bodies over owner's volume). Only the
``max_clusters`` largest clusters are kept, which bounds the number of regions.
"""

from __future__ import annotations

import numpy as np

from shared.broadphase.base import Frame
from shared.broadphase.hdbc import hdbc
from shared.broadphase.nonuniform import NonUniformDetector, region_counts, region_volumes


class CBASS(NonUniformDetector):
    name = "cbass"

    def __init__(self, k: int = 8, delta: float = 0.5, sample: int = 20000, max_clusters: int = 6,
                 min_fraction: float = 0.02, seed: int = 0, refit_every: int = 0) -> None:
        super().__init__(refit_every=refit_every)
        self.k, self.delta, self.sample = k, delta, sample
        self.max_clusters, self.min_fraction, self.seed = max_clusters, min_fraction, seed
        self.boxes: np.ndarray = np.zeros((0, 2, 3))

    def fit_splits(self, frame: Frame, lo: np.ndarray, hi: np.ndarray):
        c = frame.centres
        n = c.shape[0]
        rng = np.random.default_rng(self.seed)
        pts = c if n <= self.sample else c[rng.choice(n, self.sample, replace=False)]
        cl = hdbc(pts, k=self.k, delta=self.delta, min_size=max(self.k + 1, int(self.min_fraction * len(pts))))
        sizes = np.bincount(cl.labels[cl.labels >= 0], minlength=cl.n_clusters)
        keep = sorted(np.argsort(-sizes, kind="stable")[: self.max_clusters])  # densest first
        boxes = [(pts[cl.labels == q].min(axis=0), pts[cl.labels == q].max(axis=0)) for q in keep]
        self.boxes = np.array(boxes).reshape(-1, 2, 3)
        splits = []
        for a in range(3):
            s = [lo[a], hi[a]] + [b[0][a] for b in boxes] + [b[1][a] for b in boxes]
            s = np.unique(np.clip(np.asarray(s), lo[a], hi[a]))
            splits.append(s)
        xs, ys, zs = splits
        mid = np.stack(np.meshgrid((xs[:-1] + xs[1:]) / 2, (ys[:-1] + ys[1:]) / 2,
                                   (zs[:-1] + zs[1:]) / 2, indexing="ij"), axis=-1).reshape(-1, 3)
        owner = np.full(mid.shape[0], -1)
        for q in range(len(boxes) - 1, -1, -1):  # the densest box written last wins
            inside = np.all((mid >= self.boxes[q, 0]) & (mid <= self.boxes[q, 1]), axis=1)
            owner[inside] = q
        counts = region_counts(c, xs, ys, zs)
        vols = region_volumes(xs, ys, zs)
        density = np.empty(mid.shape[0])
        for q in range(-1, len(boxes)):
            sel = owner == q
            if sel.any():
                density[sel] = counts[sel].sum() / max(vols[sel].sum(), 1e-300)
        return xs, ys, zs, density
