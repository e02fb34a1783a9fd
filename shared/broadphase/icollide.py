"""I-COLLIDE-style incremental sweep-and-prune (Cohen, Lin et al.; thesis §5.1.2, §5.2.5).

The order of the boxes along x is kept from frame to frame and repaired by insertion sort, which
costs O(n + swaps): nearly linear while bodies move little relative to their spacing (strong
temporal coherence), quadratic in the worst case. That is the dependence on SPEED that the
thesis measures (Table 5.3). I-COLLIDE also keeps the set of overlapping boxes up to date from
the swaps on all three axes; here the x order is carried over and the overlapping set is
recomputed by one sweep over it, which finds the same pairs with less bookkeeping (the swap
count, the part that depends on coherence, is the same).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shared.broadphase.base import Detector, Frame
from shared.broadphase.scd import finish, sweep_sorted


@njit(cache=True)
def insertion_sort_order(order, keys):
    """Repair ``order`` so that ``keys[order]`` ascends; returns the number of swaps."""
    n = order.shape[0]
    swaps = 0
    for a in range(1, n):
        i = order[a]
        key = keys[i]
        b = a - 1
        while b >= 0 and keys[order[b]] > key:
            order[b + 1] = order[b]
            b -= 1
            swaps += 1
        order[b + 1] = i
    return swaps


class ICollide(Detector):
    """Sweep-and-prune along x with the order carried over between frames."""

    name = "icollide"

    def __init__(self) -> None:
        self._order: np.ndarray | None = None
        self.last_swaps = 0

    def _update(self, frame: Frame) -> np.ndarray:
        c, r = frame.centres, frame.radii
        n = c.shape[0]
        keys = c[:, 0] - (r + frame.pad)
        if self._order is None or self._order.shape[0] != n:
            self._order = np.argsort(keys, kind="stable")
            self.last_swaps = 0
        else:
            self.last_swaps = int(insertion_sort_order(self._order, keys))
        return finish(sweep_sorted(self._order, c, r, frame.pad), n)

    def reset(self) -> None:
        self._order = None
