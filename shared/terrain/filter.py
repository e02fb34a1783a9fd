"""Grid-density filter of seed 004 §2: before a point joins the triangulation, the mesh density
is fixed from the number of points, and a point whose ground (XY) projection lies closer than
that spacing to a point already accepted is dropped.

Done in one pass in input order with a hash grid of cell = spacing, so each point looks at the
accepted points of 3 x 3 cells only: O(N). Dropping near-duplicates also keeps the Delaunay
triangulation free of slivers and coincident sites.
"""

from __future__ import annotations

import numba
import numpy as np

from shared.errors import InputError

#: default spacing as a fraction of the mean ground spacing sqrt(area / N)
DEFAULT_DENSITY_FACTOR = 0.35


def mean_spacing(points: np.ndarray) -> float:
    """sqrt(ground area / N): the spacing of the cloud if its points were on a square grid."""
    extent = np.ptp(points[:, :2], axis=0)
    return float(np.sqrt(max(extent[0] * extent[1], 1e-18) / len(points)))


@numba.njit(cache=True)
def _filter_kernel(xy: np.ndarray, spacing: float) -> np.ndarray:
    n = xy.shape[0]
    lo0 = xy[:, 0].min()
    lo1 = xy[:, 1].min()
    nx = int((xy[:, 0].max() - lo0) / spacing) + 3
    ny = int((xy[:, 1].max() - lo1) / spacing) + 3
    # a linked list of accepted points per cell, in a hash table of 2N buckets
    nb = 2 * n + 1
    head = np.full(nb, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    keep = np.zeros(n, np.bool_)
    r2 = spacing * spacing
    for p in range(n):
        ci = int((xy[p, 0] - lo0) / spacing) + 1
        cj = int((xy[p, 1] - lo1) / spacing) + 1
        near = False
        for di in range(-1, 2):
            for dj in range(-1, 2):
                h = ((ci + di) * ny + (cj + dj)) % nb
                q = head[h]
                while q >= 0:
                    dx = xy[q, 0] - xy[p, 0]
                    dy = xy[q, 1] - xy[p, 1]
                    if dx * dx + dy * dy < r2:
                        near = True
                        break
                    q = nxt[q]
                if near:
                    break
            if near:
                break
        if not near:
            keep[p] = True
            h = (ci * ny + cj) % nb
            nxt[p] = head[h]
            head[h] = p
    return keep


def grid_density_filter(points: np.ndarray, spacing: float | None = None, factor: float = DEFAULT_DENSITY_FACTOR) -> np.ndarray:
    """Indices of the points kept, in input order. ``spacing`` (m) is the ground distance under
    which a later point is dropped; by default ``factor`` times the mean spacing of the cloud."""
    points = np.asarray(points, dtype=float)
    if len(points) == 0:
        raise InputError("grid-density filter: the cloud is empty")
    if spacing is None:
        if not factor > 0:
            raise InputError(f"grid-density filter: factor must be > 0, got {factor}")
        spacing = factor * mean_spacing(points)
    if not spacing > 0 or not np.isfinite(spacing):
        raise InputError(f"grid-density filter: spacing must be a positive length, got {spacing}")
    keep = _filter_kernel(np.ascontiguousarray(points[:, :2]), float(spacing))
    return np.flatnonzero(keep)
