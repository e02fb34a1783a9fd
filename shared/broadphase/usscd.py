"""USSCD (thesis §5.2.3): uniform subdivision with the cost-model cell size, sort-and-sweep
inside each cell.

The bounding box of the bodies is taken afresh each frame (cheap, and bodies that drift out of
a nominal cube stay correct); the cell side comes from the §5.2.2 model with the frame's point
density and ``w`` = the largest box edge (the largest diameter). The thesis keeps each cell's
order in an AVL tree updated by insertions and deletions; here each frame re-sorts the short
per-column lists (insertion sort, nearly linear on the order carried over from the last frame),
which does the same job with less bookkeeping and parallelises (see ``grid.py``). Cells are never
narrower than the largest diameter (the model's ``2w`` is wider anyway).
"""

from __future__ import annotations

import numpy as np

from shared.broadphase.base import Detector, Frame, sort_pairs
from shared.broadphase.costmodel import cell_size
from shared.broadphase.grid import GridEngine, make_partition, min_cell


class USSCD(Detector):
    """Uniform space subdivision collision detection.

    ``cell`` overrides the cost model's cell side (used by the benchmark's sweep over cell
    sizes); ``max_columns_per_body`` bounds the column count for very sparse scenes.
    """

    name = "usscd"

    def __init__(self, cell: float | None = None, max_columns_per_body: float = 64.0) -> None:
        self.cell = cell
        self.max_columns_per_body = max_columns_per_body
        self._engine = GridEngine()
        self.last_cell = float("nan")

    def _update(self, frame: Frame) -> np.ndarray:
        centres, radii, pad = frame.centres, frame.radii, frame.pad
        n = centres.shape[0]
        lo = frame.lo - frame.rmax
        extent = np.maximum(frame.hi + frame.rmax - lo, 1e-9)
        w = max(2.0 * frame.rmax, 1e-9)
        l = self.cell if self.cell is not None else cell_size(n / float(np.prod(extent)), w)
        l = max(l, min_cell(frame.rmax, pad))
        part = make_partition([lo[0], lo[0] + extent[0]], [lo[1], lo[1] + extent[1]],
                              [lo[2], lo[2] + extent[2]], [l],
                              max_columns=int(self.max_columns_per_body * n) + 16)
        self.last_cell = float(part.cell[0])
        return sort_pairs(self._engine.pairs(centres, radii, part, pad, frame.rmax), n)

    def reset(self) -> None:
        self._engine = GridEngine()
