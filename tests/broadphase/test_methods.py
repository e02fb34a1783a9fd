"""Every method must return exactly the brute-force pairs, frame after frame."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.broadphase import METHODS, make_detector
from shared.broadphase.workloads import make_scene
from shared.errors import InputError, UnknownNameError

FAST = [m for m in METHODS if m != "brute"]


def run_against_brute(scene, frames: int, methods=FAST, **options) -> int:
    """Step the scene, compare every method with brute force; returns pairs seen in total."""
    dets = {m: make_detector(m, **options.get(m, {})) for m in methods}
    ref_det = make_detector("brute")
    seen = 0
    for f in range(frames):
        ref = ref_det.update(scene.centres, scene.radii)
        seen += len(ref)
        for m, d in dets.items():
            got = d.update(scene.centres, scene.radii)
            assert got.dtype == np.int64 and got.shape[1] == 2
            assert np.array_equal(got, ref), f"{m} differs from brute force at frame {f}: {len(got)} vs {len(ref)} pairs"
        scene.step()
    return seen


@pytest.mark.parametrize("kind", ["uniform", "gaussian", "sediment"])
def test_moving_scenes_match_brute_force(kind):
    # dense enough that contacts happen every frame; radii vary; fast motion breaks coherence
    scene = make_scene(kind, n=400, density=0.004, speed=0.7, radius_spread=0.6, seed=11)
    assert run_against_brute(scene, frames=300) > 300


def test_thesis_density_scene_matches_brute_force():
    scene = make_scene("uniform", n=2048, speed=0.5, seed=3)  # Table 5.1's last column
    assert run_against_brute(scene, frames=40) > 0


def test_parallel_kernels_on_a_large_scene():
    # above grid.PARALLEL_MIN the parallel kernels run (two threads, chunked sweeps)
    scene = make_scene("gaussian", n=21000, density=0.002, seed=8)
    methods = ["usscd", "usscd_skin", "pbnuss", "cbass", "ugrid", "ugrid_skin"]
    assert run_against_brute(scene, frames=3, methods=methods) > 1000


def test_high_speed_and_refits():
    scene = make_scene("gaussian", n=300, density=0.01, speed=6.4, seed=5)
    opts = {"pbnuss": {"refit_every": 7}, "cbass": {"refit_every": 5}}
    run_against_brute(scene, frames=120, **opts)


def lattice(n_side: int, spacing: float, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    g = np.arange(n_side) * spacing
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3) + np.asarray(origin)


@pytest.mark.parametrize("method", FAST)
def test_exactly_touching_lattice_on_cell_boundaries(method):
    # spheres of radius 1 at spacing 2: every axis neighbour touches exactly; centres sit on
    # multiples of 2, i.e. on every border of 4-wide cells
    c = lattice(6, 2.0)
    ref = make_detector("brute").update(c, 1.0)
    assert len(ref) == 3 * 6 * 6 * 5  # the 180 face contacts, and no more
    det = make_detector(method)
    assert np.array_equal(det.update(c, 1.0), ref)
    assert np.array_equal(det.update(c + 1e-300, 1.0), ref)


@pytest.mark.parametrize("method", FAST)
def test_touching_with_inexact_numbers(method):
    # radii and offsets that are not exact in binary: the decision is whatever the one shared
    # predicate says, and every method must say the same
    rng = np.random.default_rng(7)
    n = 300
    r = rng.uniform(0.05, 0.3, n)
    c = rng.uniform(0, 6, (n, 3))
    for i in range(0, n - 1, 2):  # make each even/odd couple touch along a random axis
        a = rng.integers(3)
        c[i + 1] = c[i]
        c[i + 1, a] = c[i, a] + (r[i] + r[i + 1])
    ref = make_detector("brute").update(c, r)
    assert np.array_equal(make_detector(method).update(c, r), ref)


@pytest.mark.parametrize("method", ["pbnuss", "cbass"])
def test_bodies_on_region_boundaries_and_outside_the_fitted_box(method):
    scene = make_scene("gaussian", n=600, density=0.002, seed=4)
    det = make_detector(method)
    brute = make_detector("brute")
    det.update(scene.centres, scene.radii)
    part = det.partition
    rng = np.random.default_rng(1)
    c = scene.centres.copy()
    # snap coordinates onto region splits, one axis at a time
    for a, splits in enumerate((part.xs, part.ys, part.zs)):
        pick = rng.random(len(c)) < 0.3
        c[pick, a] = rng.choice(splits, pick.sum())
    assert np.array_equal(det.update(c, scene.radii), brute.update(c, scene.radii))
    # everything shifted far beyond the fitted box (indices are clamped, answers unchanged)
    far = c * 3.0 - 500.0
    assert np.array_equal(det.update(far, scene.radii * 3.0), brute.update(far, scene.radii * 3.0))


@pytest.mark.parametrize("method", FAST)
def test_body_count_can_change_between_frames(method):
    det = make_detector(method)
    brute = make_detector("brute")
    for n, seed in ((200, 1), (350, 2), (2, 3), (0, 4), (1, 5), (120, 6)):
        s = make_scene("uniform", n=n, density=0.003, seed=seed) if n > 0 else None
        c = s.centres if s else np.zeros((0, 3))
        r = s.radii if s else np.zeros(0)
        assert np.array_equal(det.update(c, r), brute.update(c, r))


coords = st.sampled_from([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 7.9, 8.0])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(coords, coords, coords, st.sampled_from([0.25, 0.5, 1.0])), min_size=2, max_size=40))
def test_any_small_scene_with_ties_matches_brute_force(bodies):
    arr = np.array(bodies, dtype=float)
    c, r = arr[:, :3], arr[:, 3]
    ref = make_detector("brute").update(c, r)
    for m in FAST:
        assert np.array_equal(make_detector(m).update(c, r), ref), m


def test_pairs_are_sorted_and_unique():
    scene = make_scene("gaussian", n=500, density=0.01, seed=9)
    p = make_detector("usscd").update(scene.centres, scene.radii)
    assert len(p) > 0
    assert (p[:, 0] < p[:, 1]).all()
    key = p[:, 0] * 500 + p[:, 1]
    assert (np.diff(key) > 0).all()


def test_bad_input_is_refused():
    det = make_detector("usscd")
    with pytest.raises(InputError):
        det.update(np.zeros((3, 2)), 1.0)
    with pytest.raises(InputError):
        det.update(np.zeros((3, 3)), np.ones(4))
    with pytest.raises(InputError):
        det.update(np.array([[0, 0, np.nan], [1, 1, 1]]), 1.0)
    with pytest.raises(InputError):
        det.update(np.zeros((2, 3)), -1.0)
    with pytest.raises(UnknownNameError):
        make_detector("octree")


@pytest.mark.parametrize("n", [2, 9, 1001, 60_007])  # the serial pass and, from 50,000, the parallel one
def test_frame_checks_find_any_bad_value_and_exact_bounds(n):
    # the frame's pass keeps running extremes in 24 lanes per thread: every coordinate and radius
    # position, the last few bodies (the lanes' tail) included, is checked and bounded
    from shared.broadphase.base import frame_stats

    rng = np.random.default_rng(n)
    c = rng.normal(size=(n, 3)) * 50.0
    r = rng.uniform(0.0, 2.0, n)
    ok, lo, hi, amax, rmax = frame_stats(c, r)
    assert ok
    assert np.array_equal(lo, c.min(axis=0)) and np.array_equal(hi, c.max(axis=0))
    assert amax == np.abs(c).max() and rmax == r.max()
    for i in sorted({0, n // 2, max(0, n - 8), n - 1}):
        for k in range(3):
            for bad in (np.nan, np.inf, -np.inf):
                c2 = c.copy()
                c2[i, k] = bad
                assert not frame_stats(c2, r)[0], (i, k, bad)
        for bad in (np.nan, np.inf, -1e-300):
            r2 = r.copy()
            r2[i] = bad
            assert not frame_stats(c, r2)[0], (i, bad)
    r2 = r.copy()
    r2[n - 1] = -0.0  # a zero radius, signed or not, is a point
    assert frame_stats(c, r2)[0]
