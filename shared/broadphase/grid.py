"""The subdivision engine shared by USSCD, PBNUSS and CBASS: space cut into axis-aligned boxes
(a rectilinear partition: split planes per axis, one region per box), each region cut uniformly
into square columns of its own cell side, sort-and-sweep along z inside each column.

Why columns: a uniform grid of cubic cells whose per-cell lists are sorted along z is the same
as columns of stacked cells whose sorted lists are concatenated (the thesis's USSCD keeps one
sorted list per cell, §5.2.3); stacking lets the z sweep prune across z cell borders without
visiting neighbour cells, and the number of columns grows with area, not volume, so sparse
scenes do not pay for empty cells the way the thesis's 3-D grid does (§5.2.5, Table 5.2).

As in the thesis, every body's box is entered in each column it overlaps (with cells at least a
diameter wide: at most four in one region), so two overlapping bodies share a column; a pair is
reported only by the column holding the lowest corner of the two boxes' intersection (a point
inside both boxes), hence exactly once, also across region borders.

All frame work is numba: the bodies are first gathered in the order of the last frame's columns
(temporal coherence: later passes then walk memory nearly in sequence), entries are written in
parallel, counting-sorted by column with one histogram per thread, and the columns are sorted
(insertion sort on a scratch key array) and swept in parallel chunks. Small scenes use serial
compilations of the same kernels (``kernel_for``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import get_num_threads, njit, prange

from shared.broadphase.base import serial_twin, sphere_overlap

N_CHUNKS_PER_THREAD = 8
#: below this many bodies the kernels run serially: a parallel launch costs 3-200 us (OpenMP /
#: workqueue layer) and a busy machine can stall it far longer
PARALLEL_MIN = 20000

_SERIAL: dict = {}


def kernel_for(kernel, n: int):
    """The parallel kernel, or for small ``n`` a serial compilation of the same function."""
    if n >= PARALLEL_MIN:
        return kernel
    f = _SERIAL.get(kernel)
    if f is None:
        f = _SERIAL[kernel] = njit(cache=True)(serial_twin(kernel.py_func))
    return f


@dataclass(frozen=True)
class Partition:
    """A rectilinear partition of a box of space, each box with a uniform column grid.

    ``xs``, ``ys``, ``zs``: split coordinates per axis (first = lower bound, last = upper);
    region ``b = (ix * ny + iy) * nz + iz``. ``cell[b]`` its cell side, ``ncx[b]``, ``ncy[b]``
    its number of columns along x and y, ``col_off[b]`` its first global column index;
    ``n_columns`` the total. Points outside the outer box belong to the nearest region and
    column (indices are clamped), so bodies that leave the box are still handled exactly.
    """

    xs: np.ndarray
    ys: np.ndarray
    zs: np.ndarray
    cell: np.ndarray
    ncx: np.ndarray
    ncy: np.ndarray
    col_off: np.ndarray
    n_columns: int

    @property
    def n_regions(self) -> int:
        return int(self.cell.shape[0])


def make_partition(xs, ys, zs, cell_sizes, max_columns: int | None = None) -> Partition:
    """Build a partition from split coordinates and one cell side per region (same order as
    ``Partition``). ``max_columns`` caps the total column count by enlarging every cell of a
    region alike (keeps memory bounded for absurdly sparse scenes)."""
    xs = np.ascontiguousarray(xs, dtype=np.float64)
    ys = np.ascontiguousarray(ys, dtype=np.float64)
    zs = np.ascontiguousarray(zs, dtype=np.float64)
    nx, ny, nz = len(xs) - 1, len(ys) - 1, len(zs) - 1
    cell = np.ascontiguousarray(np.broadcast_to(np.asarray(cell_sizes, dtype=np.float64), (nx * ny * nz,))).copy()
    ex = np.repeat(np.diff(xs), ny * nz)
    ey = np.tile(np.repeat(np.diff(ys), nz), nx)
    for _ in range(60):
        ncx = np.maximum(1, np.ceil(ex / cell)).astype(np.int64)
        ncy = np.maximum(1, np.ceil(ey / cell)).astype(np.int64)
        total = int((ncx * ncy).sum())
        if max_columns is None or total <= max_columns:
            break
        cell = cell * np.sqrt(total / max_columns) * 1.01
    col_off = np.zeros(len(cell), dtype=np.int64)
    col_off[1:] = np.cumsum(ncx * ncy)[:-1]
    return Partition(xs, ys, zs, cell, ncx, ncy, col_off, total)


# ---------------------------------------------------------------------------------------------
# numba kernels


@njit(inline="always", cache=True)
def _region(splits, v):
    """Index k of the slab [splits[k], splits[k+1]) holding v, clamped to the outer slabs."""
    lo = 0
    hi = splits.shape[0] - 2
    while lo < hi:
        mid = (lo + hi + 1) >> 1
        if splits[mid] <= v:
            lo = mid
        else:
            hi = mid - 1
    return lo


@njit(inline="always", cache=True)
def _col(v, origin, l, n):
    c = np.floor((v - origin) / l)
    if c < 0.0:
        return 0
    if c > n - 1:
        return n - 1
    return int(c)


@njit(parallel=True, cache=True)
def _gather(centres, radii, perm, pc, pr):
    for k in prange(perm.shape[0]):
        i = perm[k]
        pc[k, 0] = centres[i, 0]
        pc[k, 1] = centres[i, 1]
        pc[k, 2] = centres[i, 2]
        pr[k] = radii[i]


@njit(parallel=True, cache=True)
def _count_entries(c, r, pad, xs, ys, zs, cell, ncx, ncy, counts):
    n = c.shape[0]
    ny = ys.shape[0] - 1
    nz = zs.shape[0] - 1
    for i in prange(n):
        h = r[i] + pad
        x0, x1 = c[i, 0] - h, c[i, 0] + h
        y0, y1 = c[i, 1] - h, c[i, 1] + h
        kx0, kx1 = _region(xs, x0), _region(xs, x1)
        ky0, ky1 = _region(ys, y0), _region(ys, y1)
        kz0, kz1 = _region(zs, c[i, 2] - h), _region(zs, c[i, 2] + h)
        total = 0
        for kx in range(kx0, kx1 + 1):
            for ky in range(ky0, ky1 + 1):
                for kz in range(kz0, kz1 + 1):
                    b = (kx * ny + ky) * nz + kz
                    l = cell[b]
                    nxc = _col(x1, xs[kx], l, ncx[b]) - _col(x0, xs[kx], l, ncx[b]) + 1
                    nyc = _col(y1, ys[ky], l, ncy[b]) - _col(y0, ys[ky], l, ncy[b]) + 1
                    total += nxc * nyc
        counts[i] = total


@njit(parallel=True, cache=True)
def _write_entries(c, r, pad, xs, ys, zs, cell, ncx, ncy, col_off, offsets, ent_col, ent_prim):
    """Every column (of every region) that a body's box overlaps. ``ent_prim`` marks the
    column holding the body's centre (it carries the body order over to the next frame)."""
    n = c.shape[0]
    ny = ys.shape[0] - 1
    nz = zs.shape[0] - 1
    for i in prange(n):
        h = r[i] + pad
        x, y, z = c[i, 0], c[i, 1], c[i, 2]
        x0, x1 = x - h, x + h
        y0, y1 = y - h, y + h
        kx0, kx1 = _region(xs, x0), _region(xs, x1)
        ky0, ky1 = _region(ys, y0), _region(ys, y1)
        kz0, kz1 = _region(zs, z - h), _region(zs, z + h)
        home = _owner_column(x, y, z, xs, ys, zs, cell, ncx, ncy, col_off)
        k = offsets[i]
        for kx in range(kx0, kx1 + 1):
            for ky in range(ky0, ky1 + 1):
                for kz in range(kz0, kz1 + 1):
                    b = (kx * ny + ky) * nz + kz
                    l = cell[b]
                    ca0 = _col(x0, xs[kx], l, ncx[b])
                    ca1 = _col(x1, xs[kx], l, ncx[b])
                    cb0 = _col(y0, ys[ky], l, ncy[b])
                    cb1 = _col(y1, ys[ky], l, ncy[b])
                    for ca in range(ca0, ca1 + 1):
                        for cb in range(cb0, cb1 + 1):
                            g = col_off[b] + ca * ncy[b] + cb
                            ent_col[k] = g
                            ent_prim[k] = 1 if g == home else 0
                            k += 1


@njit(parallel=True, cache=True)
def _write_entries_uniform(c, r, pad, ox, oy, l, ncx, ncy, ent_col, ent_prim):
    """One region: a box spans at most two columns per axis (cell >= diameter), so each body
    owns four entry slots; unused ones get column -1."""
    n = c.shape[0]
    for i in prange(n):
        h = r[i] + pad
        x, y = c[i, 0], c[i, 1]
        ca0 = _col(x - h, ox, l, ncx)
        ca1 = _col(x + h, ox, l, ncx)
        cb0 = _col(y - h, oy, l, ncy)
        cb1 = _col(y + h, oy, l, ncy)
        home = _col(x, ox, l, ncx) * ncy + _col(y, oy, l, ncy)
        k = 4 * i
        for ca in range(ca0, ca1 + 1):
            for cb in range(cb0, cb1 + 1):
                g = ca * ncy + cb
                ent_col[k] = g
                ent_prim[k] = 1 if g == home else 0
                k += 1
        while k < 4 * i + 4:
            ent_col[k] = -1
            ent_prim[k] = 0
            k += 1


@njit(cache=True)
def _owner_column(px, py, pz, xs, ys, zs, cell, ncx, ncy, col_off):
    """Global column (region and column within it) that holds the point p."""
    ny = ys.shape[0] - 1
    nz = zs.shape[0] - 1
    kx = _region(xs, px)
    ky = _region(ys, py)
    kz = _region(zs, pz)
    b = (kx * ny + ky) * nz + kz
    l = cell[b]
    return col_off[b] + _col(px, xs[kx], l, ncx[b]) * ncy[b] + _col(py, ys[ky], l, ncy[b])


@njit(parallel=True, cache=True)
def _counting_sort(ent_col, ent_prim, offsets, n_columns, n_threads, s_loc, s_prim):
    """Scatter the entries into column order (only the body's position in the gathered arrays
    and the home flag move: 5 bytes an entry); returns the column starts (n_columns + 1). Body
    ranges are split between threads, each with its own histogram; as the bodies come in the
    last frame's column order, the writes are nearly sequential."""
    n = offsets.shape[0] - 1
    hist = np.zeros((n_threads, n_columns), dtype=np.int64)
    for t in prange(n_threads):
        i0 = n * t // n_threads
        i1 = n * (t + 1) // n_threads
        for k in range(offsets[i0], offsets[i1]):
            g = ent_col[k]
            if g >= 0:
                hist[t, g] += 1
    starts = np.empty(n_columns + 1, dtype=np.int64)
    acc = 0
    for g in range(n_columns):
        starts[g] = acc
        for t in range(n_threads):
            v = hist[t, g]
            hist[t, g] = acc
            acc += v
    starts[n_columns] = acc
    for t in prange(n_threads):
        i0 = n * t // n_threads
        i1 = n * (t + 1) // n_threads
        pos = hist[t]
        for i in range(i0, i1):
            for k in range(offsets[i], offsets[i + 1]):
                g = ent_col[k]
                if g < 0:
                    continue
                p = pos[g]
                pos[g] = p + 1
                s_loc[p] = i
                s_prim[p] = ent_prim[k]
    return starts


@njit(cache=True)
def _order_column(s, e, pad, s_loc, c, r, key, idx, key2, idx2):
    """Order of one column's entries by the lower z of their boxes, into ``idx[:n]`` (keys in
    ``key[:n]``). Bodies arrive in the last frame's (column, z) order, so a column's list is a
    few sorted runs (one per neighbouring home column): a natural merge sort merges them in
    about n * log2(runs) steps; short lists use insertion sort."""
    n = e - s
    for a in range(n):
        i = s_loc[s + a]
        key[a] = c[i, 2] - (r[i] + pad)
        idx[a] = s + a
    if n <= 16:
        for a in range(1, n):
            kk = key[a]
            ii = idx[a]
            b = a - 1
            while b >= 0 and key[b] > kk:
                key[b + 1] = key[b]
                idx[b + 1] = idx[b]
                b -= 1
            key[b + 1] = kk
            idx[b + 1] = ii
        return
    src_k, src_i, dst_k, dst_i = key, idx, key2, idx2
    flipped = False
    while True:
        # one pass: merge neighbouring runs pairwise from src into dst
        a = 0
        runs = 0
        while a < n:
            m = a + 1
            while m < n and src_k[m - 1] <= src_k[m]:
                m += 1
            if m >= n:  # a last unpaired run: copy
                for t in range(a, n):
                    dst_k[t] = src_k[t]
                    dst_i[t] = src_i[t]
                runs += 1
                break
            b = m + 1
            while b < n and src_k[b - 1] <= src_k[b]:
                b += 1
            i, j, t = a, m, a
            while i < m and j < b:
                if src_k[j] < src_k[i]:
                    dst_k[t] = src_k[j]
                    dst_i[t] = src_i[j]
                    j += 1
                else:
                    dst_k[t] = src_k[i]
                    dst_i[t] = src_i[i]
                    i += 1
                t += 1
            while i < m:
                dst_k[t] = src_k[i]
                dst_i[t] = src_i[i]
                i += 1
                t += 1
            while j < b:
                dst_k[t] = src_k[j]
                dst_i[t] = src_i[j]
                j += 1
                t += 1
            runs += 1
            a = b
        src_k, src_i, dst_k, dst_i = dst_k, dst_i, src_k, src_i
        flipped = not flipped
        if runs <= 1:
            break
    if flipped:  # the sorted data is in the second scratch pair
        for t in range(n):
            key[t] = key2[t]
            idx[t] = idx2[t]


@njit(cache=True)
def _sweep_chunk(g0, g1, starts, pad, s_loc, s_prim, c, r, ids,
                 xs, ys, zs, cell, ncx, ncy, col_off, out, base, cap, key, idx, key2, idx2,
                 perm_out, prim_starts):
    """Sort and sweep columns g0..g1-1 (``c``, ``r``: the bodies gathered in the last frame's
    order, ``ids`` their indices); writes at most ``cap`` pairs from ``out[base]`` and returns how
    many it found. Also writes this column's home bodies, in z order, to ``perm_out``."""
    k = 0
    for g in range(g0, g1):
        s = starts[g]
        e = starts[g + 1]
        n = e - s
        if n == 0:
            continue
        _order_column(s, e, pad, s_loc, c, r, key, idx, key2, idx2)
        w = prim_starts[g]
        for u in range(n):
            if s_prim[idx[u]]:
                perm_out[w] = ids[s_loc[idx[u]]]
                w += 1
        for u in range(n):  # entry positions -> body positions
            idx[u] = s_loc[idx[u]]
        for u in range(n - 1):
            a = idx[u]
            ra = r[a]
            ha = ra + pad
            xa = c[a, 0]
            ya = c[a, 1]
            za = c[a, 2]
            top = za + ha
            for v in range(u + 1, n):
                if key[v] > top:
                    break
                j = idx[v]
                rb = r[j]
                hb = rb + pad
                xb = c[j, 0]
                yb = c[j, 1]
                if abs(xb - xa) > ha + hb or abs(yb - ya) > ha + hb:
                    continue
                zb = c[j, 2]
                if not sphere_overlap(xa, ya, za, ra, xb, yb, zb, rb):
                    continue
                # report only in the column holding the low corner of the boxes' overlap
                px = max(xa - ha, xb - hb)
                py = max(ya - ha, yb - hb)
                pz = max(za - ha, zb - hb)
                if _owner_column(px, py, pz, xs, ys, zs, cell, ncx, ncy, col_off) != g:
                    continue
                if k < cap:
                    out[base + k, 0] = ids[a]
                    out[base + k, 1] = ids[j]
                k += 1
    return k


@njit(parallel=True, cache=True)
def _sweep(starts, chunk_bounds, pad, s_loc, s_prim, c, r, ids,
           xs, ys, zs, cell, ncx, ncy, col_off, out, cap, counts, longest, perm_out, prim_starts):
    for q in prange(chunk_bounds.shape[0] - 1):
        key = np.empty(longest)
        idx = np.empty(longest, dtype=np.int64)
        key2 = np.empty(longest)
        idx2 = np.empty(longest, dtype=np.int64)
        counts[q] = _sweep_chunk(chunk_bounds[q], chunk_bounds[q + 1], starts, pad, s_loc, s_prim,
                                 c, r, ids, xs, ys, zs, cell, ncx, ncy, col_off, out,
                                 q * cap, cap, key, idx, key2, idx2, perm_out, prim_starts)


class GridEngine:
    """Per-frame runner of the column subdivision over a given ``Partition``.

    Between frames it keeps the body order of the last frame's sorted columns (temporal
    coherence, the role the thesis gives its per-cell AVL trees): the bodies are gathered in that
    order first, so every later pass walks memory nearly in sequence and the per-column
    insertion sorts have little to do. It also keeps the last pair count to size the output.
    """

    def __init__(self) -> None:
        self._expected_pairs = 0
        self._perm: np.ndarray | None = None
        self._buffers: dict[str, np.ndarray] = {}

    def _buf(self, name: str, size: int, dtype, cols: int = 0) -> np.ndarray:
        """A reusable work array (fresh large allocations cost page faults every frame)."""
        b = self._buffers.get(name)
        if b is None or b.shape[0] < size or b.dtype != np.dtype(dtype):
            shape = (max(size, 1) + max(size, 1) // 4,) + ((cols,) if cols else ())
            b = self._buffers[name] = np.empty(shape, dtype=dtype)
        return b[:size]

    def pairs(self, centres: np.ndarray, radii: np.ndarray, part: Partition, pad: float,
              rmax: float) -> np.ndarray:
        """Unsorted ``(K, 2)`` int array of overlapping pairs (each once). Every region's cell
        side must be at least the largest diameter plus padding (``min_cell``)."""
        n = centres.shape[0]
        n_threads = max(1, get_num_threads()) if n >= PARALLEL_MIN else 1
        perm = self._perm
        if perm is None or perm.shape[0] != n:
            perm = np.arange(n, dtype=np.int32 if n < 2**31 else np.int64)
        pc = self._buf("pc", n, np.float64, 3)
        pr = self._buf("pr", n, np.float64)
        kernel_for(_gather, n)(centres, radii, perm, pc, pr)
        col_type = np.int32 if part.n_columns < 2**31 else np.int64
        uniform = part.n_regions == 1 and float(part.cell[0]) >= 2.0 * (rmax + pad)
        if uniform:
            offsets = np.arange(0, 4 * n + 1, 4, dtype=np.int64)
            ent_col = self._buf("ent_col", 4 * n, col_type)
            ent_prim = self._buf("ent_prim", 4 * n, np.uint8)
            kernel_for(_write_entries_uniform, n)(pc, pr, pad, float(part.xs[0]), float(part.ys[0]), float(part.cell[0]),
                                   int(part.ncx[0]), int(part.ncy[0]), ent_col, ent_prim)
        else:
            counts = np.empty(n, dtype=np.int64)
            kernel_for(_count_entries, n)(pc, pr, pad, part.xs, part.ys, part.zs, part.cell, part.ncx, part.ncy, counts)
            offsets = np.zeros(n + 1, dtype=np.int64)
            np.cumsum(counts, out=offsets[1:])
            ent_col = self._buf("ent_col", int(offsets[-1]), col_type)
            ent_prim = self._buf("ent_prim", int(offsets[-1]), np.uint8)
            kernel_for(_write_entries, n)(pc, pr, pad, part.xs, part.ys, part.zs, part.cell, part.ncx, part.ncy,
                           part.col_off, offsets, ent_col, ent_prim)
        m = ent_col.shape[0]  # slots; the filled ones are counted by the sort
        s_loc = self._buf("s_loc", m, np.int32 if n < 2**31 else np.int64)
        s_prim = self._buf("s_prim", m, np.uint8)
        starts = kernel_for(_counting_sort, n)(ent_col, ent_prim, offsets, part.n_columns, n_threads,
                                               s_loc, s_prim)
        m = int(starts[-1])
        n_chunks = max(1, min(part.n_columns, n_threads * N_CHUNKS_PER_THREAD))
        targets = np.linspace(0, m, n_chunks + 1)  # chunks of about equal entry counts
        chunk_bounds = np.searchsorted(starts, targets, side="left").astype(np.int64)
        chunk_bounds[0] = 0
        chunk_bounds[-1] = part.n_columns
        chunk_bounds = np.maximum.accumulate(chunk_bounds)
        longest = max(1, int(np.diff(starts).max(initial=1)))
        # where each column's home bodies go in next frame's order
        prim_pos = np.flatnonzero(s_prim[:m])
        prim_starts = np.searchsorted(prim_pos, starts).astype(np.int64)
        perm_out = np.empty(prim_pos.shape[0], dtype=perm.dtype)
        cap = max(64, (2 * self._expected_pairs) // n_chunks + 64)
        while True:
            out = self._buf("out", n_chunks * cap, np.int64, 2)
            found = np.zeros(n_chunks, dtype=np.int64)
            kernel_for(_sweep, n)(starts, chunk_bounds, pad, s_loc, s_prim, pc, pr, perm, part.xs, part.ys,
                   part.zs, part.cell, part.ncx, part.ncy, part.col_off, out, cap, found, longest,
                                  perm_out, prim_starts)
            if found.max() <= cap:
                break
            cap = int(found.max())  # the sweep only reads: a rerun finds the same pairs
        self._expected_pairs = int(found.sum())
        self._perm = perm_out
        if self._perm.shape[0] != n:
            self._perm = None
        keep = (np.arange(cap)[None, :] < found[:, None]).ravel()
        return out[keep]


def min_cell(rmax: float, pad: float) -> float:
    """Smallest cell side the engine accepts: touching bodies must be in adjacent columns."""
    return (2.0 * (rmax + pad)) * (1.0 + 1e-9) + 1e-12
