"""SCD (thesis §5.2.5): sort-and-sweep over all bodies, no subdivision.

Each frame the boxes are sorted by their lower x bound and swept: a body is tested against the
following ones while their lower x does not pass its upper x. The thesis sorts with an AVL tree
(binary insertion, O(n log n) whatever the motion); a full sort per frame has the same
complexity and no dependence on the previous frame, which is the property the thesis relies on
when it compares SCD with I-COLLIDE's insertion sort.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shared.broadphase.base import PAIR_DTYPE, Detector, Frame, sphere_overlap


@njit(cache=True)
def sweep_sorted(order, c, r, pad):
    """Pairs among bodies taken in ``order`` (sorted by lower x bound), box-pruned on x, y, z
    and decided by the sphere predicate. Returns an unsorted (K, 2) array."""
    n = order.shape[0]
    xs = np.empty(n)
    hs = np.empty(n)
    for k in range(n):
        i = order[k]
        hs[k] = r[i] + pad
        xs[k] = c[i, 0]
    out = np.empty((64, 2), dtype=np.int64)
    m = 0
    for a in range(n):
        i = order[a]
        ha = hs[a]
        top = xs[a] + ha
        yi, zi, ri = c[i, 1], c[i, 2], r[i]
        for b in range(a + 1, n):
            hb = hs[b]
            if xs[b] - hb > top:
                break
            j = order[b]
            if abs(c[j, 1] - yi) > ha + hb or abs(c[j, 2] - zi) > ha + hb:
                continue
            if sphere_overlap(c[i, 0], yi, zi, ri, c[j, 0], c[j, 1], c[j, 2], r[j]):
                if m == out.shape[0]:
                    bigger = np.empty((2 * m, 2), dtype=np.int64)
                    bigger[:m] = out
                    out = bigger
                out[m, 0] = i
                out[m, 1] = j
                m += 1
    return out[:m]


def finish(pairs: np.ndarray, n: int) -> np.ndarray:
    from shared.broadphase.base import sort_pairs

    return sort_pairs(pairs, n).astype(PAIR_DTYPE)


class SCD(Detector):
    """Sort (from scratch) and sweep along x."""

    name = "scd"

    def _update(self, frame: Frame) -> np.ndarray:
        c, r = frame.centres, frame.radii
        order = np.argsort(c[:, 0] - (r + frame.pad), kind="stable")
        return finish(sweep_sorted(order, c, r, frame.pad), c.shape[0])
