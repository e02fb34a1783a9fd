"""The engineered grid (``ugrid``, ``ugrid_skin``): exact against brute force on every code path of
the column engine - one-block, wide-block and block-after-block filters, the parallel kernels,
bodies on column borders, the skin list and its plain stretches in crowded scenes."""

from __future__ import annotations

import numpy as np
import pytest

from shared.broadphase import columns, grid, make_detector
from shared.broadphase.columns import BLOCK, HUGE, WIDE, ColumnEngine
from shared.broadphase.workloads import make_scene

GRIDS = ["ugrid", "ugrid_skin"]


def same_as_brute(det, centres, radii) -> int:
    ref = make_detector("brute").update(centres, radii)
    got = det.update(centres, radii)
    assert got.dtype == np.int64
    assert np.array_equal(got, ref), f"{len(got)} pairs vs {len(ref)} from brute force"
    return len(ref)


@pytest.mark.parametrize("method", GRIDS)
@pytest.mark.parametrize("kind", ["uniform", "sediment"])
def test_two_thousand_frames_match_brute_force(method, kind):
    scene = make_scene(kind, n=150, density=0.01, speed=0.4, radius_spread=0.5, seed=21)
    det = make_detector(method)
    seen = 0
    for _ in range(2000):
        seen += same_as_brute(det, scene.centres, scene.radii)
        scene.step()
    assert seen > 2000  # contacts on most frames


@pytest.mark.parametrize("method", GRIDS)
def test_crowded_columns_take_every_filter_width(method):
    # a thin vertical tube (one or two columns holding far more than HUGE bodies), a slab of
    # columns holding between BLOCK and WIDE, and a sparse background: all three filters run
    rng = np.random.default_rng(3)
    tube = np.column_stack([rng.uniform(0, 1.5, 400), rng.uniform(0, 1.5, 400), rng.uniform(0, 300, 400)])
    slab = np.column_stack([rng.uniform(20, 28, 600), rng.uniform(0, 6, 600), rng.uniform(0, 40, 600)])
    background = rng.uniform(0, 300, (300, 3))
    c = np.vstack([tube, slab, background])
    r = rng.uniform(0.5, 1.0, len(c))
    assert 400 > HUGE > WIDE > BLOCK
    det = make_detector(method)
    for step in range(30):  # moving, so the carried-over order and the skin list are exercised
        assert same_as_brute(det, c, r) > 0 or step > 0
        c = c + rng.normal(0, 0.15, c.shape)


@pytest.mark.parametrize("method", GRIDS)
def test_touching_pairs_across_column_borders(method):
    # centres exactly on the column borders the detector uses, each with a partner at exactly
    # the contact distance on the other side of the border, along x, y and diagonally
    r = 1.0
    seed_scene = make_scene("uniform", n=200, size=60.0, seed=2)
    probe = make_detector("ugrid")
    probe.update(seed_scene.centres, r)
    cell = probe.last_cell
    lo = seed_scene.centres.min(axis=0)
    pts = []
    for i in range(1, 8):
        for j in range(1, 8):
            p = lo + np.array([i * cell, j * cell, 5.0 * (i + j)])
            pts += [p, p - np.array([2 * r, 0.0, 0.0]), p + np.array([0.0, 2 * r, 0.0]),
                    p + np.array([np.sqrt(2.0), np.sqrt(2.0), 0.0])]
    c = np.vstack([seed_scene.centres, np.array(pts)])
    assert np.array_equal(c.min(axis=0)[:2], lo[:2])  # same grid origin: the borders are as built
    det = make_detector(method)
    assert same_as_brute(det, c, r) >= 2 * 49


@pytest.mark.parametrize("kind", ["uniform", "gaussian"])
def test_parallel_kernels_exact_on_many_frames(kind, monkeypatch):
    # the parallel binning, scattering and testing (body parts handed out one at a time, a pair
    # buffer per part), made to run on a scene small enough for brute force
    monkeypatch.setattr(grid, "PARALLEL_MIN", 500)
    monkeypatch.setattr(columns, "PARALLEL_MIN", 500)
    scene = make_scene(kind, n=3000, density=0.003, speed=0.5, seed=13)
    dets = [make_detector(m) for m in GRIDS]
    for _ in range(40):
        ref = make_detector("brute").update(scene.centres, scene.radii)
        assert len(ref) > 10
        for det in dets:
            assert np.array_equal(det.update(scene.centres, scene.radii), ref)
        scene.step()


def test_skin_list_is_skipped_in_crowded_scenes_and_kept_in_sparse_ones():
    dense = make_scene("gaussian", n=1500, density=0.002, speed=0.3, seed=4)
    sparse = make_scene("uniform", n=1500, density=0.0005, speed=0.3, seed=4)
    d_dense = make_detector("ugrid_skin")
    d_sparse = make_detector("ugrid_skin")
    brute = make_detector("brute")
    for _ in range(50):
        assert np.array_equal(d_dense.update(dense.centres, dense.radii), brute.update(dense.centres, dense.radii))
        assert np.array_equal(d_sparse.update(sparse.centres, sparse.radii),
                              brute.update(sparse.centres, sparse.radii))
        dense.step()
        sparse.step()
    assert d_dense.plain_runs > 25  # the list was too long to pay: plain frames instead
    assert d_sparse.plain_runs == 0 and d_sparse.rebuilds >= 8


def test_very_sparse_scene_widens_the_columns_and_stays_exact():
    det = make_detector("ugrid", max_columns_per_body=1.0)
    scene = make_scene("uniform", n=50, size=400.0, seed=6)
    scene.centres[1] = scene.centres[0] + [1.2, 0.9, 0.0]  # one contact to find
    assert same_as_brute(det, scene.centres, scene.radii) >= 1
    assert det.last_cell > 2.0 * 1.0 * 1.01  # wider than the diameter: the column budget
    extent = np.ptp(scene.centres[:, :2], axis=0)
    assert (extent[0] / det.last_cell + 1) * (extent[1] / det.last_cell + 1) <= 50 + 16


def test_engine_keeps_the_last_frame_order():
    # the next frame's gather order is the column order of this one (temporal coherence)
    scene = make_scene("uniform", n=500, density=0.005, seed=7)
    eng = ColumnEngine()
    lo, hi = scene.centres.min(axis=0), scene.centres.max(axis=0)
    eng.pairs(scene.centres, scene.radii, lo, hi, 2.5, 1.0 + 1e-9)
    order = eng._perm.copy()
    assert sorted(order.tolist()) == list(range(500))
    cols = np.floor((scene.centres[order, 0] - lo[0]) / 2.5) * np.ceil((hi[1] - lo[1]) / 2.5) + \
        np.floor((scene.centres[order, 1] - lo[1]) / 2.5)
    assert (np.diff(cols) >= 0).all()


@pytest.mark.parametrize("method", GRIDS)
def test_gaussian_clouds_with_crowded_columns_match_brute_force(method):
    # dense Gaussian clouds (the scene the issue names as losing most): columns through a cloud
    # core hold several times the uniform occupancy, their neighbour ranges take the wide and
    # block-after-block filters; exact on every frame while the clouds churn
    scene = make_scene("gaussian", n=2500, density=0.004, speed=0.5, radius_spread=0.3, seed=31)
    det = make_detector(method)
    probe = make_detector("ugrid")
    probe.update(scene.centres, scene.radii)
    cell = probe.last_cell
    lo = scene.centres.min(axis=0)
    cols = np.floor((scene.centres[:, :2] - lo[:2]) / cell).astype(np.int64)
    _, counts = np.unique(cols[:, 0] * 100000 + cols[:, 1], return_counts=True)
    assert counts.max() > WIDE  # some column alone is crowded past the wide filter
    for _ in range(60):
        same_as_brute(det, scene.centres, scene.radii)
        scene.step()


@pytest.mark.parametrize("kind", ["uniform", "gaussian", "sediment"])
def test_carried_order_gives_the_same_pairs_as_a_fresh_detector(kind):
    # the engine keeps the last frame's column order (frame-to-frame reuse); a detector that
    # carried it over 40 frames and one built fresh for each frame find identical pair sets
    scene = make_scene(kind, n=2000, density=0.002, speed=0.4, seed=17)
    carried = make_detector("ugrid")
    for step in range(40):
        got = carried.update(scene.centres, scene.radii)
        fresh = make_detector("ugrid").update(scene.centres, scene.radii)
        assert np.array_equal(got, fresh)
        if step % 8 == 0:
            assert np.array_equal(got, make_detector("brute").update(scene.centres, scene.radii))
        scene.step()


@pytest.mark.parametrize("parallel", [False, True])
@pytest.mark.parametrize("thresholds", [(0, 0), (3, 8), (columns.SORT_MIN, columns.ZWIN_MIN)])
def test_heavily_clustered_scene_z_windows_match_brute_force(parallel, thresholds, monkeypatch):
    # Gaussian clouds in a small cube: columns of tens of bodies, kept sorted by z and tested
    # through z windows (every column at thresholds (0, 0); a mix of windowed and filtered
    # columns at (3, 8); the defaults). Moving, so the carried-over z order is exercised too.
    if parallel:
        monkeypatch.setattr(grid, "PARALLEL_MIN", 500)
        monkeypatch.setattr(columns, "PARALLEL_MIN", 500)
    scene = make_scene("gaussian", n=6000, size=60.0, speed=0.5, radius_spread=0.4, seed=5, clusters=2)
    det = make_detector("ugrid")
    det._engine = ColumnEngine(*thresholds)
    sort_min = det._engine.sort_min
    crowded = 0
    for _ in range(12):
        assert same_as_brute(det, scene.centres, scene.radii) > 1000
        c = scene.centres
        cols = np.floor((c[:, :2] - c[:, :2].min(axis=0)) / det.last_cell).astype(np.int64)
        crowded = max(crowded, int(np.unique(cols, axis=0, return_counts=True)[1].max()))
        scene.step()
    assert crowded > max(sort_min, HUGE)  # the crowded path really ran


def test_a_pair_touching_at_exactly_the_reach_inside_one_crowded_column_is_found():
    """A crowded column (more than ZWIN_MIN bodies, so kept sorted by z and tested through z
    windows) holding a vertical stack of equal spheres, each touching the next at exactly the
    contact distance straight up: |dz| is the whole reach (the largest diameter, up to the
    rounding pad), the window's very edge. Beside it, in the neighbouring column, a second stack
    touches the first at exactly the contact distance along a 3-4-5 diagonal. Every pair is found,
    as brute force finds it."""
    r = 2.5  # contact distance 5: z steps of 5 and the (3, 0, 4) diagonal are exact in floating point
    n = columns.ZWIN_MIN + 36
    z = 5.0 * np.arange(n)
    column = np.column_stack([np.full(n, 4.0), np.full(n, 40.0), z])
    beside = np.column_stack([np.full(n, 7.0), np.full(n, 40.0), z + 4.0])  # (3, 0, 4) from its partner
    origin = np.array([[0.0, 0.0, -500.0], [80.0, 80.0, 1000.0]])  # far corners: the grid's origin at 0
    c = np.vstack([column, beside, origin])
    radii = np.full(len(c), r)
    det = make_detector("ugrid")
    ref = make_detector("brute").update(c, radii)
    got = det.update(c, radii)
    assert int(np.floor(4.0 / det.last_cell)) != int(np.floor(7.0 / det.last_cell))  # two columns
    stack = {(i, i + 1) for i in range(n - 1)}  # the touching pairs straight up, |dz| = 5
    diagonal = {(i, n + i) for i in range(n)}  # the touching pairs across the columns
    assert stack | diagonal <= {tuple(p) for p in ref.tolist()}
    assert np.array_equal(got, ref), f"{len(got)} pairs vs {len(ref)} from brute force"


@pytest.mark.parametrize("extent", [20.0, 600.0, 3.0e6, 2.0**70])
def test_float32_filter_reach_covers_every_pair_within_reach(extent):
    # the filter compares float32 copies of the centres with a widened reach (filter_frame);
    # pairs at exactly the reach, anywhere in the box and in any direction, must all pass it,
    # computed as the kernel does (float32 differences, squares and sums)
    rng = np.random.default_rng(11)
    reach = 2.0
    lo = np.array([-0.3, 0.1, -0.2]) * extent
    hi = lo + extent
    scale, reach2 = columns.filter_frame(lo, hi, reach)
    freach2 = np.float32(reach2)
    assert freach2 == reach2  # a float32 value
    origin = lo
    m = 200_000
    a = lo + rng.uniform(0.0, 1.0, (m, 3)) * (hi - lo)
    a[: m // 4] = np.where(rng.random((m // 4, 3)) < 0.5, lo, hi)  # corners: the largest copies
    d = rng.normal(size=(m, 3))
    d *= reach / np.linalg.norm(d, axis=1)[:, None]
    b = a + d
    inside = np.all((b >= lo) & (b <= hi), axis=1)
    assert inside.sum() > m // 4
    fa = ((a[inside] - origin) * scale).astype(np.float32)
    fb = ((b[inside] - origin) * scale).astype(np.float32)
    fd = fb - fa
    d2 = fd[:, 0] * fd[:, 0] + fd[:, 1] * fd[:, 1] + fd[:, 2] * fd[:, 2]
    assert d2.dtype == np.float32
    assert np.all(d2 <= freach2)
    # and it stays a filter: pairs at 3x the reach are rejected unless float32 cannot tell
    if extent * 2.0**-20 < reach:
        far = ((a[inside] + 3.0 * d[inside] - origin) * scale).astype(np.float32) - fa
        assert np.mean(far[:, 0] ** 2 + far[:, 1] ** 2 + far[:, 2] ** 2 > freach2) > 0.99


@pytest.mark.parametrize("method", GRIDS)
@pytest.mark.parametrize("offset", [3.0e6, 2.0**70])
def test_touching_and_nearly_touching_pairs_far_from_the_origin(method, offset):
    # groups spread over `offset`, so the float32 copies resolve only about offset * 2^-24: pairs
    # at exactly the contact distance, a hair beyond it and a hair inside, which the float32
    # filter cannot tell apart and the float64 predicate must. Equal radii: the contact distance
    # is the filter's whole reach. Groups of 20 bodies: each fills one (wide) column, filtered
    # rather than taking the z windows of crowded columns
    rng = np.random.default_rng(5)
    pts = []
    for g in range(6):
        base = offset * g / 5.0 * np.array([1.0, 1.0 / 3.0, -1.0 / 7.0])
        for k in range(10):
            p = base + rng.uniform(0, 40, 3)
            u = rng.normal(size=3)
            u /= np.linalg.norm(u)
            gap = 2.0 * (1.0 + (0.0, 1e-9, -1e-9)[k % 3])
            pts += [p, p + gap * u]
    c = np.array(pts)
    r = np.ones(len(c))
    ref = make_detector("brute").update(c, r)
    assert len(ref) >= 20  # the inside ones at least (exactly touching may round either way)
    det = make_detector(method)
    for _ in range(3):
        assert np.array_equal(det.update(c, r), ref)
