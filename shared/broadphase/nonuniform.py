"""Two-level non-uniform subdivision (thesis §5.3.1): a coarse rectilinear partition fitted to
the distribution once (the distribution is assumed stable over time, so the partition is kept
and refitted only every ``refit_every`` frames or when N changes), then each region subdivided
uniformly with the §5.2 cost model applied to the region's own density. The frame work is the
shared column engine (``grid.py``); PBNUSS and CBASS differ only in how they place the splits.
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from shared.broadphase.base import Detector, Frame, sort_pairs
from shared.broadphase.costmodel import cell_size
from shared.broadphase.grid import GridEngine, Partition, make_partition, min_cell


def region_counts(centres: np.ndarray, xs: np.ndarray, ys: np.ndarray, zs: np.ndarray) -> np.ndarray:
    """Number of centres in each region of the product partition (same order as Partition)."""
    nx, ny, nz = len(xs) - 1, len(ys) - 1, len(zs) - 1
    ix = np.clip(np.searchsorted(xs, centres[:, 0], side="right") - 1, 0, nx - 1)
    iy = np.clip(np.searchsorted(ys, centres[:, 1], side="right") - 1, 0, ny - 1)
    iz = np.clip(np.searchsorted(zs, centres[:, 2], side="right") - 1, 0, nz - 1)
    return np.bincount((ix * ny + iy) * nz + iz, minlength=nx * ny * nz)


def region_volumes(xs: np.ndarray, ys: np.ndarray, zs: np.ndarray) -> np.ndarray:
    dx, dy, dz = np.diff(xs), np.diff(ys), np.diff(zs)
    return (dx[:, None, None] * dy[None, :, None] * dz[None, None, :]).ravel()


def cells_for_densities(density: np.ndarray, frame: Frame) -> np.ndarray:
    """Cost-model cell side per region, never below what the engine needs."""
    w = max(2.0 * frame.rmax, 1e-9)
    floor = min_cell(frame.rmax, frame.pad)
    return np.array([max(cell_size(float(d), w), floor) for d in density])


class NonUniformDetector(Detector):
    """Common part of PBNUSS and CBASS: keep a fitted partition, run the engine on it."""

    def __init__(self, refit_every: int = 0, max_columns_per_body: float = 64.0) -> None:
        self.refit_every = refit_every
        self.max_columns_per_body = max_columns_per_body
        self._engine = GridEngine()
        self.partition: Partition | None = None
        self._fitted_n = -1
        self._frames = 0

    @abstractmethod
    def fit_splits(self, frame: Frame, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Split coordinates per axis (including ``lo`` and ``hi``) and a density per region."""

    def fit(self, frame: Frame) -> Partition:
        lo = frame.lo - frame.rmax
        hi = np.maximum(frame.hi + frame.rmax, lo + 1e-9)
        xs, ys, zs, density = self.fit_splits(frame, lo, hi)
        n = frame.centres.shape[0]
        return make_partition(xs, ys, zs, cells_for_densities(density, frame),
                              max_columns=int(self.max_columns_per_body * n) + 16)

    def _update(self, frame: Frame) -> np.ndarray:
        n = frame.centres.shape[0]
        stale = self.refit_every > 0 and self._frames % self.refit_every == 0
        if self.partition is None or n != self._fitted_n or stale:
            self.partition = self.fit(frame)
            self._fitted_n = n
        else:
            floor = min_cell(frame.rmax, frame.pad)
            if float(self.partition.cell.min()) < floor:  # radii grew: cells must follow
                self.partition = self.fit(frame)
        self._frames += 1
        pairs = self._engine.pairs(frame.centres, frame.radii, self.partition, frame.pad, frame.rmax)
        return sort_pairs(pairs, n)

    def reset(self) -> None:
        self._engine = GridEngine()
        self.partition = None
        self._fitted_n = -1
        self._frames = 0
