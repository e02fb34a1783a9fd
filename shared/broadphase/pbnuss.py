"""PBNUSS (thesis §5.3.2): projection-histogram non-uniform subdivision.

Per axis: a histogram of the centres with about ``per_bin`` bodies per bin (bin width
``per_bin * L / n``), then region growing along the axis: a region absorbs its right neighbour
while their densities agree within the relative threshold ``T`` (``|D_i - D| <= T * max(D_i, D)``),
in rounds until nothing merges. If more than ``max_regions`` slabs remain, the most similar
neighbours are merged. The three axis partitions form the 3-D partition (their product).
"""

from __future__ import annotations

import numpy as np

from shared.broadphase.base import Frame
from shared.broadphase.nonuniform import NonUniformDetector, region_counts, region_volumes


def grow_regions(edges: np.ndarray, counts: np.ndarray, threshold: float, max_regions: int) -> np.ndarray:
    """Region growing over one histogram; returns the kept split coordinates (with both ends)."""
    e = list(edges.astype(float))
    c = list(counts.astype(float))
    merged = True
    while merged and len(c) > 1:
        merged = False
        ne, nc = [e[0]], []
        cur_c, cur_lo = c[0], e[0]
        for i in range(1, len(c)):
            d_cur = cur_c / (e[i] - cur_lo)
            d_i = c[i] / (e[i + 1] - e[i])
            if abs(d_i - d_cur) <= threshold * max(d_i, d_cur, 1e-300):
                cur_c += c[i]
                merged = True
            else:
                nc.append(cur_c)
                ne.append(e[i])
                cur_c, cur_lo = c[i], e[i]
        nc.append(cur_c)
        ne.append(e[-1])
        e, c = ne, nc
    while len(c) > max_regions:  # merge the most alike neighbours
        dens = [c[i] / (e[i + 1] - e[i]) for i in range(len(c))]
        gaps = [abs(dens[i + 1] - dens[i]) / max(dens[i], dens[i + 1], 1e-300) for i in range(len(c) - 1)]
        i = int(np.argmin(gaps))
        c[i:i + 2] = [c[i] + c[i + 1]]
        del e[i + 1]
    return np.asarray(e)


class PBNUSS(NonUniformDetector):
    name = "pbnuss"

    def __init__(self, per_bin: float = 32.0, threshold: float = 0.5, max_regions: int = 8,
                 refit_every: int = 0) -> None:
        super().__init__(refit_every=refit_every)
        self.per_bin = per_bin
        self.threshold = threshold
        self.max_regions = max_regions

    def fit_splits(self, frame: Frame, lo: np.ndarray, hi: np.ndarray):
        c = frame.centres
        n = c.shape[0]
        splits = []
        for a in range(3):
            bins = int(np.clip(np.ceil(n / self.per_bin), 1, 65536))
            counts, edges = np.histogram(c[:, a], bins=bins, range=(lo[a], hi[a]))
            splits.append(grow_regions(edges, counts, self.threshold, self.max_regions))
        xs, ys, zs = splits
        density = region_counts(c, xs, ys, zs) / region_volumes(xs, ys, zs)
        return xs, ys, zs, density
