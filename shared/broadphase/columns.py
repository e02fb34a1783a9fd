"""The engine of ``ugrid`` and ``ugrid_skin`` (engineered for speed, not in the thesis): one
uniform grid of square columns as narrow as the largest diameter, each body entered once (in
the column holding its centre), every body tested against the bodies after it in its column and
in the half neighbourhood of columns through a fixed-width, branch-free distance filter.

Why this form (measured on 2 cores against the multi-entry engine of ``grid.py`` that USSCD,
PBNUSS and CBASS use): at the densities of the sedimentation scenes a column of that width holds
one to a few bodies. Sorting and sweeping such short lists costs a mispredicted branch for
almost every loop (the sweep's exit tests depend on the data), and entering a body in every
column its box overlaps writes about 2.25 entries a body. Here:

* the §5.2.2 cost model, applied to an engine without boundary bands (a body is entered once),
  grows with the cell side, so the side is the smallest the neighbourhood rule allows: the
  largest diameter (two touching bodies are then in the same or in neighbouring columns);
* the candidates of body ``a`` are two memory ranges: the rest of its column followed by column
  (x, y+1), which is adjacent in memory, and the three columns (x+1, y-1 .. y+1), also
  adjacent. Each range is tested by loops of constant length without branches (a squared
  centre distance against the largest contact distance, on float32 copies of the centres with
  the reach widened by their rounding bound, ``filter_frame``): the first BLOCK candidates of
  every body in one pass vectorised across bodies, the rest HUGE at a time; only the
  candidates that pass, of the bodies with a hit, meet the exact float64 predicate (see
  ``_test_bodies``). Each unordered pair of neighbouring columns is visited from one side only,
  so every pair is found exactly once;
* temporal coherence (the role of the thesis's AVL trees): the bodies are kept in the last
  frame's column order. Each frame they are binned in that order, so the counting sort by column
  moves memory nearly in sequence and the sorted copies stay close to last frame's;
* crowded columns (more than SORT_MIN bodies, beyond the clustered scenes measured) are kept
  sorted by z, the order carried into the next frame like the column order, and their bodies
  test only the z window ``|dz| <= reach`` of each neighbour column through pointers that only
  move up, instead of filtering every body of the neighbourhood;
* two threads: body ranges per thread with a histogram each for binning and scattering, equal
  body ranges with a pair buffer each for the tests. Small scenes run serial compilations of
  the same kernels.
"""

from __future__ import annotations

import math

import numpy as np
from numba import get_num_threads, get_parallel_chunksize, njit, prange, set_parallel_chunksize
from numba.cpython.unsafe.numbers import trailing_zeros

from shared.broadphase.base import sphere_overlap
from shared.broadphase.grid import PARALLEL_MIN, kernel_for
from shared.broadphase.prefetch import prefetch

#: body ranges per thread in the test pass (load balance on clustered scenes, and on a machine
#: shared with other jobs: ranges are handed out one at a time, so a thread that the system
#: holds back leaves its remaining ranges to the other)
CHUNKS_PER_THREAD = 4
#: body ranges per thread for binning and scattering (each with its own histogram). One: the
#: histograms' zeroing and prefix sum are per column (about one a body), and two ranges a thread
#: cost more in them than they gained in balance (interleaved, 100k, 2 threads: 2.42-2.83
#: against 2.56-2.88 ms a frame on the sediment scene, 1.91-1.93 against 2.03-2.06 uniform)
PARTS_PER_THREAD = 1
#: width of the branch-free filter (one AVX-512 register of float64, two AVX2 ones) ...
BLOCK = 8
#: ... and its width in crowded neighbourhoods (measured best: 8 and 16)
WIDE = 16
HUGE = 32
#: how many bodies ahead the gathering asks for a centre (measured: 8-64 alike) ...
PREFETCH_AHEAD = 8
#: ... and the exact predicate for the rows of a body with a hit (measured: 2-8 alike)
HIT_AHEAD = 4
#: columns holding more bodies than this are kept sorted by z (heavy clusters) ...
SORT_MIN = 64
#: ... and the bodies of a column holding more than this many (at least SORT_MIN) test only the
#: z window |dz| <= reach of each sorted neighbour column, followed by a rising pointer,
#: instead of filtering every body there. A guard against columns crowded far beyond the
#: scenes measured: since the filter vectorises, filtering whole columns of up to 64 bodies is
#: faster than sorting and windowing them (Gaussian 1M, 2 threads, columns of 13 bodies on
#: average and up to 41: 68 ms a frame with both thresholds at 16, 47 ms at 32-64 or with
#: neither; at 100k no difference)
ZWIN_MIN = 64


@njit(inline="always", cache=True)
def _cell(v, origin, inv, n):
    """The cell of coordinate v, clamped to 0 .. n - 1 (in floating point, before the
    conversion, which truncates: the floor for the non-negative values left; branch-free,
    4% off the gathering against a floor and two tests)."""
    return int(min(max((v - origin) * inv, 0.0), n - 1.0))


@njit(parallel=True, cache=True)
def _gather_bin(centres, radii, perm, ox, oy, inv, ncx, ncy, rows, key, hist, n_parts):
    """Bodies in the last frame's order: rows (x, y, z, r), column, one histogram per part.
    Column (x, y) of the ``ncx`` by ``ncy`` grid is number ``x * (ncy + 2) + y + 1``: the grid
    is stored with an empty row of columns on either side in y and an empty column after the
    last in x, so every body's neighbour columns exist (see ``_test_bodies``)."""
    n = perm.shape[0]
    flat = centres.reshape(-1)
    for t in prange(n_parts):
        h = hist[t]
        h[:] = 0
        end = n * (t + 1) // n_parts
        for k in range(n * t // n_parts, end):
            if k + PREFETCH_AHEAD < end:  # the read order is random in memory: ask ahead
                j = np.uint64(perm[k + PREFETCH_AHEAD])
                prefetch(flat, np.uint64(3) * j)
                prefetch(radii, j)
            i = perm[k]
            x = centres[i, 0]
            y = centres[i, 1]
            rows[k, 0] = x
            rows[k, 1] = y
            rows[k, 2] = centres[i, 2]
            rows[k, 3] = radii[i]
            g = _cell(x, ox, inv, ncx) * (ncy + 2) + _cell(y, oy, inv, ncy) + 1
            key[k] = g
            h[g] += 1


@njit(cache=True)
def _offsets(hist, starts):
    """Exclusive prefix over (column, part): ``hist[t, g]`` becomes part t's first slot in
    column g; ``starts`` (n_columns + 1) the column starts. Returns the largest column."""
    n_threads, n_columns = hist.shape
    acc = 0
    largest = 0
    for g in range(n_columns):
        starts[g] = acc
        for t in range(n_threads):
            v = hist[t, g]
            hist[t, g] = acc
            acc += v
        largest = max(largest, acc - starts[g])
    starts[n_columns] = acc
    return largest


@njit(parallel=True, cache=True)
def _scatter(rows, perm, key, hist, n_parts, starts, src, ids, col, first_end, fx, fy, fz, origin, scale):
    """Stable counting sort into column order: the float32 copies of the centres the filter
    reads, ``(c - origin) * scale``, the body's row in ``rows`` (where the exact predicate reads
    its float64 centre and radius: nearly in sequence, since this frame's column order is
    nearly the last one's), body ids, columns, and the end of each body's first range of
    candidates (the start of column (x, y+2)). Float64 copies in column order as well cost more
    to write than the exact predicate, run for about one body in six, saves reading them."""
    n = perm.shape[0]
    for t in prange(n_parts):
        pos = hist[t]
        for k in range(n * t // n_parts, n * (t + 1) // n_parts):
            g = key[k]
            p = pos[g]
            pos[g] = p + 1
            src[p] = k
            fx[p] = np.float32((rows[k, 0] - origin[0]) * scale)
            fy[p] = np.float32((rows[k, 1] - origin[1]) * scale)
            fz[p] = np.float32((rows[k, 2] - origin[2]) * scale)
            ids[p] = perm[k]
            col[p] = g
            first_end[p] = starts[g + 2]


@njit(parallel=True, cache=True)
def _sort_columns(starts, n_columns, n_parts, rows, src, ids, fx, fy, fz, sort_min):
    """Insertion sort by z of every column holding more than ``sort_min`` bodies. The order is
    kept into the next frame (``ids`` becomes its body order), so the columns arrive nearly
    sorted and the sort costs about one comparison a body."""
    for t in prange(n_parts):
        for g in range(n_columns * t // n_parts, n_columns * (t + 1) // n_parts):
            s = starts[g]
            e = starts[g + 1]
            if e - s <= sort_min:
                continue
            for i in range(s + 1, e):
                z = rows[src[i], 2]
                if rows[src[i - 1], 2] <= z:
                    continue
                w = src[i]
                d = ids[i]
                f0 = fx[i]
                f1 = fy[i]
                f2 = fz[i]
                j = i
                while j > s and rows[src[j - 1], 2] > z:
                    src[j] = src[j - 1]
                    ids[j] = ids[j - 1]
                    fx[j] = fx[j - 1]
                    fy[j] = fy[j - 1]
                    fz[j] = fz[j - 1]
                    j -= 1
                src[j] = w
                ids[j] = d
                fx[j] = f0
                fy[j] = f1
                fz[j] = f2


@njit(inline="always", cache=True)
def _emit(out, base, cap, k, i, j):
    if k < cap:
        out[base + k, 0] = min(i, j)
        out[base + k, 1] = max(i, j)
    return k + 1


@njit(inline="always", cache=True)
def _near_in_block(bx, by, bz, xa, ya, za, reach2, b0, b1):
    """How many of the bodies b0 .. min(b0 + BLOCK, b1) - 1 have their centre within ``reach``
    (squared: ``reach2``) of (xa, ya, za): a loop of constant length without branches (``bx``,
    ``by``, ``bz`` are padded by HUGE slots of NaN, which never count).

    The index is unsigned on purpose: with a signed one numba wraps negative indices, LLVM
    cannot prove ``b0 >= 0`` for a start read from ``starts`` and compiles the loads to
    gathers, which made this filter 5-8x slower on the neighbour columns (measured, 100k
    bodies, one thread: the test pass 12.0 -> 4.3 ms on the Gaussian scene)."""
    m = 0
    s = np.uint64(b0)
    lim = b1 - b0
    for u in range(BLOCK):
        i = s + np.uint64(u)
        dx = bx[i] - xa
        dy = by[i] - ya
        dz = bz[i] - za
        m += (dx * dx + dy * dy + dz * dz <= reach2) & (u < lim)
    return m


@njit(inline="always", cache=True)
def _test_range(a, b0, b1, rows, src, ids, out, base, cap, k):
    """The exact predicate between body a and bodies b0..b1-1 (float64 rows through ``src``)."""
    i = src[a]
    xa = rows[i, 0]
    ya = rows[i, 1]
    za = rows[i, 2]
    ra = rows[i, 3]
    for b in range(b0, b1):
        j = src[b]
        if sphere_overlap(xa, ya, za, ra, rows[j, 0], rows[j, 1], rows[j, 2], rows[j, 3]):
            k = _emit(out, base, cap, k, ids[a], ids[b])
    return k


@njit(inline="always", cache=True)
def _test_passing(a, b0, b1, rows, src, ids, fx, fy, fz, freach2, out, base, cap, k):
    """The exact predicate between body a and those of bodies b0..b1-1 that pass the filter:
    the filter 16 lanes at a time into a bit mask, then the set bits only (against the exact
    predicate on every candidate of a body with a hit: 0.3 ms less on the Gaussian 100k scene,
    one thread)."""
    i = src[a]
    xa = rows[i, 0]
    ya = rows[i, 1]
    za = rows[i, 2]
    ra = rows[i, 3]
    ga = fx[a]
    gb = fy[a]
    gc = fz[a]
    c0 = b0
    while c0 < b1:
        s = np.uint64(c0)
        lim = b1 - c0
        mask = np.uint32(0)
        for u in range(16):
            b = s + np.uint64(u)
            dx = fx[b] - ga
            dy = fy[b] - gb
            dz = fz[b] - gc
            mask |= np.uint32((dx * dx + dy * dy + dz * dz <= freach2) & (u < lim)) << np.uint32(u)
        while mask != 0:
            b = c0 + trailing_zeros(mask)
            mask &= mask - np.uint32(1)
            j = src[b]
            if sphere_overlap(xa, ya, za, ra, rows[j, 0], rows[j, 1], rows[j, 2], rows[j, 3]):
                k = _emit(out, base, cap, k, ids[a], ids[b])
        c0 += 16
    return k


@njit(inline="always", cache=True)
def _near_in_wide(bx, by, bz, xa, ya, za, reach2, b0, b1):
    """``_near_in_block`` over WIDE bodies (crowded neighbourhoods)."""
    m = 0
    s = np.uint64(b0)
    lim = b1 - b0
    for u in range(WIDE):
        i = s + np.uint64(u)
        dx = bx[i] - xa
        dy = by[i] - ya
        dz = bz[i] - za
        m += (dx * dx + dy * dy + dz * dz <= reach2) & (u < lim)
    return m


@njit(inline="always", cache=True)
def _near_in_huge(bx, by, bz, xa, ya, za, reach2, b0, b1):
    """``_near_in_block`` over HUGE bodies (crowded neighbourhoods)."""
    m = 0
    s = np.uint64(b0)
    lim = b1 - b0
    for u in range(HUGE):
        i = s + np.uint64(u)
        dx = bx[i] - xa
        dy = by[i] - ya
        dz = bz[i] - za
        m += (dx * dx + dy * dy + dz * dz <= reach2) & (u < lim)
    return m


@njit(inline="always", cache=True)
def _advance(p, e, rows, src, zlo):
    while p < e and rows[src[p], 2] < zlo:
        p += 1
    return p


@njit(inline="always", cache=True)
def _scan_window(a, xa, ya, za, ra, p, e, zhi, rows, src, ids, out, base, cap, k):
    while p < e and rows[src[p], 2] <= zhi:
        j = src[p]
        if sphere_overlap(xa, ya, za, ra, rows[j, 0], rows[j, 1], rows[j, 2], rows[j, 3]):
            k = _emit(out, base, cap, k, ids[a], ids[p])
        p += 1
    return k


@njit(inline="always", cache=True)
def _test_sorted_column(a0, a1, g, ny, starts, rows, src, ids, reach, sort_min, out, base, cap, k,
                        h_s, h_e):
    """Bodies a0..a1-1 of column g, sorted by z, against the rest of g and the half
    neighbourhood: the z window ``|dz| <= reach`` of each sorted neighbour column is followed by
    a pointer that only moves up (the bodies of g come in rising z), unsorted (short)
    neighbour columns are tested whole. ``|dz| <= reach`` is necessary for the filter's
    ``d^2 <= reach^2``, so nothing the filter would pass is skipped. ``ny``: columns in a row
    of the padded grid."""
    e_g = starts[g + 1]
    # the four neighbour columns: (x, y+1), (x+1, y-1 .. y+1), which the padding guarantees
    h_s[0] = starts[g + 1]
    h_e[0] = starts[g + 2]
    for u in range(3):
        h_s[u + 1] = starts[g + ny - 1 + u]
        h_e[u + 1] = starts[g + ny + u]
    m = 4
    for a in range(a0, a1):
        i = src[a]
        xa = rows[i, 0]
        ya = rows[i, 1]
        za = rows[i, 2]
        ra = rows[i, 3]
        zlo = za - reach
        zhi = za + reach
        k = _scan_window(a, xa, ya, za, ra, a + 1, e_g, zhi, rows, src, ids, out, base, cap, k)
        for u in range(m):
            if h_e[u] - h_s[u] > sort_min:
                h_s[u] = _advance(h_s[u], h_e[u], rows, src, zlo)
                k = _scan_window(a, xa, ya, za, ra, h_s[u], h_e[u], zhi, rows, src, ids, out, base, cap, k)
            else:
                k = _test_range(a, h_s[u], h_e[u], rows, src, ids, out, base, cap, k)
    return k


@njit(inline="always", cache=True)
def _near_in_range(bx, by, bz, xa, ya, za, reach2, b0, b1):
    """How many of the bodies b0..b1-1 pass the filter: one fixed-width loop for the short
    ranges of most bodies (the width chosen by the range's length), blocks beyond."""
    n = b1 - b0
    if n <= BLOCK:
        return _near_in_block(bx, by, bz, xa, ya, za, reach2, b0, b1)
    if n <= WIDE:
        return _near_in_wide(bx, by, bz, xa, ya, za, reach2, b0, b1)
    m = 0
    c0 = b0
    while c0 < b1:
        m += _near_in_huge(bx, by, bz, xa, ya, za, reach2, c0, b1)
        c0 += HUGE
    return m


@njit(cache=True)
def _test_bodies(a0, a1, starts, col, first_end, ny, rows, src, ids, reach, out, base, cap, sort_min, zwin_min,
                 fx, fy, fz, freach2):
    """Pairs whose first body is one of a0..a1-1 and whose second is later in the same column
    or in the half neighbourhood; returns how many (writes at most cap from out[base]).
    ``ny``: columns in a row of the padded grid, whose empty border columns make the neighbour
    ranges of every body three loads from ``starts``, without a branch or a division.

    Passes over the bodies: the filter on the first BLOCK candidates of the first range of
    each (the rest of its column and the column (x, y+1), adjacent in memory; its end,
    ``first_end``, written by the scatter), on the rest of that range where it is longer, on
    the second range (the columns (x+1, y-1 .. y+1), adjacent too), then the exact predicate
    for the bodies with a hit (listed first), on the candidates that pass the filter (float64
    rows through ``src``). One pass doing both filters compiled to code 2x slower than
    separate passes (measured, 100k bodies: 2.7 against 1.3 ms). Bodies of crowded columns
    (sorted by z) are marked in the third pass and take the z windows of
    ``_test_sorted_column`` in the last."""
    k = 0
    h_s = np.empty(4, dtype=np.int64)
    h_e = np.empty(4, dtype=np.int64)
    hits = np.empty(a1 - a0, dtype=np.int32)
    listed = np.empty(a1 - a0, dtype=np.int64)
    # the first BLOCK candidates of every body: a loop LLVM vectorises across bodies (the
    # candidates of consecutive bodies are consecutive; measured 4x the per-body loop)
    for a in range(a0, a1):
        hits[a - a0] = _near_in_block(fx, fy, fz, fx[a], fy[a], fz[a], freach2, a + 1, first_end[a])
    for a in range(a0, a1):
        e = first_end[a]
        if e - a - 1 > BLOCK:  # the same fixed width as the second range (below)
            m = _near_in_huge(fx, fy, fz, fx[a], fy[a], fz[a], freach2, a + 1 + BLOCK, e)
            if e - a - 1 > BLOCK + HUGE:
                m += _near_in_range(fx, fy, fz, fx[a], fy[a], fz[a], freach2, a + 1 + BLOCK + HUGE, e)
            hits[a - a0] += m
    for a in range(a0, a1):
        g = col[a]
        if starts[g + 1] - starts[g] > zwin_min:
            hits[a - a0] = -1
        else:
            # one fixed width for every body: a width chosen per body (8, 16 or 32 by the
            # range's length) cost a mispredicted branch on clustered scenes (interleaved runs,
            # 100k, one thread: 3.38 -> 2.87 ms Gaussian, 1.97 -> 1.86 ms uniform)
            b0 = starts[g + ny - 1]
            b1 = starts[g + ny + 2]
            m = _near_in_huge(fx, fy, fz, fx[a], fy[a], fz[a], freach2, b0, b1)
            if b1 - b0 > HUGE:
                m += _near_in_range(fx, fy, fz, fx[a], fy[a], fz[a], freach2, b0 + HUGE, b1)
            hits[a - a0] += m
    # the bodies with a hit, listed without a branch (a branch per body on a hit in one body
    # of ten to twenty mispredicts)
    n_hit = 0
    for a in range(a0, a1):
        listed[n_hit] = a
        n_hit += hits[a - a0] != 0
    n = src.shape[0]
    flat_rows = rows.reshape(-1)
    t = 0
    while t < n_hit:
        a = listed[t]
        if t + HIT_AHEAD < n_hit:  # the rows are read through src, out of cache: ask ahead
            ahead = listed[t + HIT_AHEAD]
            prefetch(flat_rows, np.uint64(4) * np.uint64(src[ahead]))
            prefetch(flat_rows, np.uint64(4) * np.uint64(src[min(starts[col[ahead] + ny - 1], n - 1)]))
        t += 1
        g = col[a]
        if hits[a - a0] < 0:  # a crowded column, sorted by z: z windows
            a_end = min(starts[g + 1], a1)
            k = _test_sorted_column(a, a_end, g, ny, starts, rows, src, ids, reach, sort_min,
                                    out, base, cap, k, h_s, h_e)
            while t < n_hit and listed[t] < a_end:
                t += 1
            continue
        k = _test_passing(a, a + 1, first_end[a], rows, src, ids, fx, fy, fz, freach2, out, base, cap, k)
        k = _test_passing(a, starts[g + ny - 1], starts[g + ny + 2], rows, src, ids, fx, fy, fz, freach2,
                          out, base, cap, k)
    return k


@njit(parallel=True, cache=True)
def _test_all(n_chunks, starts, col, first_end, ny, rows, src, ids, reach, out, cap, found, sort_min, zwin_min,
              fx, fy, fz, freach2):
    n = col.shape[0]
    for q in prange(n_chunks):
        found[q] = _test_bodies(n * q // n_chunks, n * (q + 1) // n_chunks, starts, col, first_end, ny,
                                rows, src, ids, reach, out, q * cap, cap, sort_min, zwin_min,
                                fx, fy, fz, freach2)


@njit(cache=True)
def _collect(out, found, cap):
    total = 0
    for q in range(found.shape[0]):
        total += found[q]
    res = np.empty((total, 2), dtype=np.int64)
    k = 0
    for q in range(found.shape[0]):
        for u in range(found[q]):
            res[k, 0] = out[q * cap + u, 0]
            res[k, 1] = out[q * cap + u, 1]
            k += 1
    return res


@njit(cache=True)
def filter_frame(lo, hi, reach):
    """How the filter's float32 copies are made, ``(c - lo) * scale``, and the squared reach
    they are compared with, wide enough that the filter passes every pair the float64 predicate
    accepts (the predicate still decides; float32 lanes halve the filter's loads and arithmetic,
    measured 17-25% off the test pass on all three scenes). Returns ``(scale, reach2)``, reach2 a
    float32 value (numba hands it back as a Python float).

    With ``E`` the largest scaled coordinate (centres lie in [lo, hi], so at most the scaled
    extent), each copy is within ``E * 2^-24`` of its scaled value, a float32 difference within
    ``E * 2^-23`` (+ its own rounding) of the scaled difference, so the float32 distance exceeds
    ``scale * |d|`` by at most ``2 * E * 2^-22`` plus relative roundings (``2^-24`` each, seven
    of them through the squares and sums): ``(scale * reach + E * 2^-21)^2 * (1 + 2^-20)``,
    rounded up to float32, is never below a computed squared distance whose true distance is
    within ``reach``. Underflow only lowers a computed distance. ``scale`` is 1 unless the
    extent passes 2^60 (then a power of two: exact), so that no square overflows float32; a
    reach whose square does (far larger than the scene) becomes infinite and lets every pair
    through, which stays exact."""
    extent = 0.0
    for d in range(lo.shape[0]):
        extent = max(extent, hi[d] - lo[d])
    scale = 1.0
    if extent > 2.0**60:
        scale = 2.0 ** -(np.ceil(np.log2(extent)) - 60.0)
    e = extent * scale
    bound = (scale * reach + e * 2.0**-21 + 2.0**-120) ** 2 * (1.0 + 2.0**-20)
    freach2 = np.float32(np.inf)
    if bound < 3.0e38:
        freach2 = np.float32(bound)
        if np.float64(freach2) < bound:
            freach2 = np.nextafter(freach2, np.float32(np.inf))
    return scale, freach2


class _Workspace:
    """The work arrays of one scene size, allocated once: fresh large arrays cost page faults
    every frame, and Python between the kernels runs cold (its data evicted by theirs: a numpy
    call there costs 3-10x its warm time), so a frame does as few Python steps as it can. The
    float32 copies keep their NaN padding (read by the fixed-width filter, never counted) from
    allocation on: the scatter writes only the first n slots."""

    def __init__(self, n: int, n_parts: int, n_columns: int) -> None:
        self.n = n
        self.n_parts = n_parts
        self.column_capacity = n_columns + n_columns // 4 + 16
        self.index_type = np.int32 if n < 2**31 else np.int64
        self.col_type = np.int32 if self.column_capacity < 2**31 else np.int64
        self.key = np.empty(n, self.col_type)
        self.hist = np.empty(n_parts * self.column_capacity, self.index_type)
        self.starts = np.empty(self.column_capacity + 1, np.int64)
        self.rows = np.empty((n, 4), np.float64)
        self.fx = np.full(n + HUGE, np.nan, np.float32)
        self.fy = np.full(n + HUGE, np.nan, np.float32)
        self.fz = np.full(n + HUGE, np.nan, np.float32)
        self.src = np.empty(n, self.index_type)
        self.col = np.empty(n, self.col_type)
        self.first_end = np.empty(n, self.index_type)
        #: where the next body order is written; the order just used becomes the spare
        self.spare = np.empty(n, self.index_type)

    def fits(self, n: int, n_parts: int, n_columns: int) -> bool:
        return self.n == n and self.n_parts == n_parts and n_columns <= self.column_capacity


class ColumnEngine:
    """Per-frame runner of the column grid; keeps the body order and buffers between frames."""

    def __init__(self, sort_min: int = SORT_MIN, zwin_min: int = ZWIN_MIN) -> None:
        self.sort_min = sort_min
        self.zwin_min = max(zwin_min, sort_min)  # only sorted columns take the z windows
        self._perm: np.ndarray | None = None
        self._expected_pairs = 0
        self._ws: _Workspace | None = None
        self._out = np.empty((0, 2), np.int64)

    def pairs(self, centres: np.ndarray, radii: np.ndarray, lo: np.ndarray, hi: np.ndarray, cell: float,
              rmax_pad: float) -> np.ndarray:
        """Unsorted ``(K, 2)`` int64 pairs ``i < j`` of overlapping bodies, each once.

        ``lo``, ``hi``: float64 arrays, a box holding the centres; ``cell``: the column side, at
        least ``min_cell`` (the largest diameter plus padding); ``rmax_pad``: the largest radius
        plus the rounding pad."""
        n = centres.shape[0]
        parallel = n >= PARALLEL_MIN
        n_threads = max(1, get_num_threads()) if parallel else 1
        n_parts = n_threads * PARTS_PER_THREAD if parallel else 1
        ox, oy = float(lo[0]), float(lo[1])
        ncx = max(1, math.ceil((float(hi[0]) - ox) / cell))
        ncy = max(1, math.ceil((float(hi[1]) - oy) / cell))
        n_columns = (ncx + 1) * (ncy + 2)  # with the empty border (see _gather_bin)
        ws = self._ws
        if ws is None or not ws.fits(n, n_parts, n_columns):
            ws = self._ws = _Workspace(n, n_parts, n_columns)
        perm = self._perm
        if perm is None or perm.shape[0] != n:
            perm = np.arange(n, dtype=ws.index_type)
        chunksize = get_parallel_chunksize()
        set_parallel_chunksize(1)  # hand out body ranges one at a time (see CHUNKS_PER_THREAD)
        try:
            return self._run(ws, centres, radii, perm, lo, hi, ox, oy, cell, rmax_pad, parallel, n_threads,
                             ncx, ncy, n_columns)
        finally:
            set_parallel_chunksize(chunksize)

    def _run(self, ws, centres, radii, perm, lo, hi, ox, oy, cell, rmax_pad, parallel, n_threads, ncx, ncy,
             n_columns) -> np.ndarray:
        n = ws.n
        n_parts = ws.n_parts
        ny = ncy + 2  # columns in a row of the padded grid (see _gather_bin)
        hist = ws.hist[: n_parts * n_columns].reshape(n_parts, n_columns)
        starts = ws.starts[: n_columns + 1]
        kernel_for(_gather_bin, n)(centres, radii, perm, ox, oy, 1.0 / cell, ncx, ncy, ws.rows, ws.key, hist,
                                   n_parts)
        largest = _offsets(hist, starts)
        reach = 2.0 * rmax_pad
        scale, reach2 = filter_frame(lo, hi, reach)
        freach2 = np.float32(reach2)
        ids = ws.spare  # becomes next frame's order
        kernel_for(_scatter, n)(ws.rows, perm, ws.key, hist, n_parts, starts, ws.src, ids, ws.col, ws.first_end,
                                ws.fx, ws.fy, ws.fz, lo, scale)
        if largest > self.sort_min:  # only heavy clusters have columns to keep in z order
            kernel_for(_sort_columns, n)(starts, n_columns, n_parts, ws.rows, ws.src, ids, ws.fx, ws.fy, ws.fz,
                                         self.sort_min)
        n_chunks = n_threads * CHUNKS_PER_THREAD if parallel else 1
        cap = max(64, (3 * self._expected_pairs) // (2 * n_chunks) + 64)
        while True:
            if self._out.shape[0] < n_chunks * cap:
                self._out = np.empty((n_chunks * cap + n_chunks * cap // 4, 2), np.int64)
            found = np.zeros(n_chunks, dtype=np.int64)
            kernel_for(_test_all, n)(n_chunks, starts, ws.col, ws.first_end, ny, ws.rows, ws.src, ids, reach,
                                     self._out, cap, found, self.sort_min, self.zwin_min, ws.fx, ws.fy, ws.fz,
                                     freach2)
            most = found.max()
            if most <= cap:
                break
            cap = int(most) + 64  # the tests only read: a rerun finds the same pairs
        self._expected_pairs = int(found.sum())
        ws.spare = perm  # same size and type: both come from this workspace's index type
        self._perm = ids
        return _collect(self._out, found, cap)
