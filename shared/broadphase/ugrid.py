"""``ugrid`` and ``ugrid_skin``: the engineered detectors (not in the thesis) built for the speed
goal of issue 8 on the column engine of ``columns.py``.

``ugrid`` is a uniform subdivision like USSCD, with three departures measured to pay on the
sedimentation scenes: each body is entered once instead of in every cell its box overlaps, the
cell side is the largest diameter (the §5.2.2 cost model without a boundary band: see
``column_side``), and the in-cell sort-and-sweep is replaced by a branch-free distance filter over
the column and its half neighbourhood (the columns hold one to a few bodies). ``ugrid_skin``
runs it with grown spheres only when a skin list expires, exactly as ``usscd_skin`` does with
USSCD (see ``verlet.py``).
"""

from __future__ import annotations

import numpy as np

from shared.broadphase.base import Detector, Frame, sort_pairs
from shared.broadphase.columns import ColumnEngine
from shared.broadphase.grid import min_cell
from shared.broadphase.verlet import SkinUSSCD


def column_side(frame: Frame, rmax: float, n: int, cell: float | None, max_columns_per_body: float) -> float:
    """The column side. The cost model of §5.2.2 is ``N (1 + 6w/l)(3 ln l + ln delta)``, the
    first factor counting bodies entered in several cells; entered once, the factor is 1 and the
    cost grows with ``l``, so the smallest side the neighbourhood rule allows is taken: the
    largest diameter (``min_cell``). It is widened only to keep at most ``max_columns_per_body``
    columns a body in very sparse scenes (memory and the per-column prefix)."""
    floor = min_cell(rmax, frame.pad)
    l = max(cell if cell is not None else floor, floor)
    ex, ey = (frame.hi - frame.lo)[:2]
    budget = max_columns_per_body * n + 16
    while (ex / l + 1.0) * (ey / l + 1.0) > budget:
        l *= 1.25
    return float(l)


class UGrid(Detector):
    """Uniform grid of columns, one entry a body, branch-free neighbour filter (two threads)."""

    name = "ugrid"

    def __init__(self, cell: float | None = None, max_columns_per_body: float = 16.0) -> None:
        self.cell = cell
        self.max_columns_per_body = max_columns_per_body
        self._engine = ColumnEngine()
        self.last_cell = float("nan")

    def _update(self, frame: Frame) -> np.ndarray:
        return sort_pairs(self.raw_pairs(frame, 0.0), frame.centres.shape[0])

    def raw_pairs(self, frame: Frame, grow: float) -> np.ndarray:
        """Unsorted pairs of the frame with every radius grown by ``grow`` (a skin list's
        candidates; 0 for the exact answer)."""
        c = frame.centres
        r = frame.radii if grow == 0.0 else frame.radii + grow
        rmax = frame.rmax + grow
        l = column_side(frame, rmax, c.shape[0], self.cell, self.max_columns_per_body)
        self.last_cell = l
        return self._engine.pairs(c, r, frame.lo, frame.hi, l, rmax + frame.pad)

    def reset(self) -> None:
        self._engine = ColumnEngine()


class SkinUGrid(SkinUSSCD):
    """The skin list of ``usscd_skin`` over ``ugrid`` instead of USSCD, skipped where it does
    not pay: a skin list holds the pairs within ``2 * skin`` of touching, whose number grows
    with the local density times (r + skin)^3, and a rebuild costs accordingly. When a list
    comes out longer than ``crowd_limit`` candidates a body (dense clusters: several times
    the cost of a plain frame to build), plain ``ugrid`` frames follow, ``plain_frames`` of them,
    doubling each time the list is found crowded again (a retry every so often notices a scene
    that thins out)."""

    name = "ugrid_skin"

    def __init__(self, frames_ahead: float = 3.0, max_skin: float = 2.0, cell: float | None = None,
                 crowd_limit: float = 0.5, plain_frames: int = 16) -> None:
        self.crowd_limit = crowd_limit
        self.plain_frames = plain_frames
        super().__init__(frames_ahead=frames_ahead, max_skin=max_skin, cell=cell)

    def reset(self) -> None:
        super().reset()
        self._grid = UGrid(cell=self.cell)
        self._plain_left = 0
        self._backoff = self.plain_frames
        #: frames answered by plain ugrid because the skin list was crowded
        self.plain_runs = 0

    def _subdivide(self, frame: Frame, grow: float) -> np.ndarray:
        """Every pair within ``2 * grow`` of touching, sorted (filtering keeps it sorted)."""
        return sort_pairs(self._grid.raw_pairs(frame, grow), frame.centres.shape[0])

    def _update(self, frame: Frame) -> np.ndarray:
        n = frame.centres.shape[0]
        if self._plain_left > 0:
            self._plain_left -= 1
            self.plain_runs += 1
            self._cand = None  # the list is stale: rebuilt when the plain stretch ends
            return sort_pairs(self._grid.raw_pairs(frame, 0.0), n)
        before = self.rebuilds
        pairs = super()._update(frame)
        if self.rebuilds > before and self._skin > 0.0:
            if self._cand.shape[0] > self.crowd_limit * n:
                self._plain_left = self._backoff
                self._backoff *= 2
            else:
                self._backoff = self.plain_frames
        return pairs
