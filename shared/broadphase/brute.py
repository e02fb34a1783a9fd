"""The reference: every pair tested with the common sphere predicate, O(N^2). Only for checking
the other methods on small scenes."""

from __future__ import annotations

import numpy as np
from numba import njit

from shared.broadphase.base import PAIR_DTYPE, Detector, Frame, sphere_overlap


@njit(cache=True)
def _all_pairs(c, r):
    n = c.shape[0]
    out = np.empty((16, 2), dtype=np.int64)
    k = 0
    for i in range(n):
        for j in range(i + 1, n):
            if sphere_overlap(c[i, 0], c[i, 1], c[i, 2], r[i], c[j, 0], c[j, 1], c[j, 2], r[j]):
                if k == out.shape[0]:
                    bigger = np.empty((2 * k, 2), dtype=np.int64)
                    bigger[:k] = out
                    out = bigger
                out[k, 0] = i
                out[k, 1] = j
                k += 1
    return out[:k].copy()


class BruteForce(Detector):
    """All N(N-1)/2 pairs; rows come out already in (i, j) lexicographic order."""

    name = "brute"

    def _update(self, frame: Frame) -> np.ndarray:
        return _all_pairs(frame.centres, frame.radii).astype(PAIR_DTYPE)
