"""The cost model, the workload and HDBC on their own."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.broadphase.costmodel import cell_size, g_of
from shared.broadphase.hdbc import hdbc
from shared.broadphase.pbnuss import grow_regions
from shared.broadphase.workloads import make_scene, side_for
from shared.errors import InputError, UnknownNameError


def model_cost(l, w, density, n=1000.0):
    return n * (1 + 6 * w / l) * (3 * math.log(l) + math.log(density))  # eq. (5.2)


def test_sparse_scenes_take_the_smallest_cell():
    # thesis density with unit spheres: 6 - 3 ln 12 - ln 0.0005 > 0, eq. (5.3)
    assert cell_size(0.0005, 2.0) == 4.0


def test_dense_scenes_take_the_cost_minimum():
    w, density = 2.0, 0.6
    assert g_of(6 * w, w, density) < 0
    l0 = cell_size(density, w)
    assert l0 >= 6 * w
    assert abs(g_of(l0, w, density)) < 1e-6
    f0 = model_cost(l0, w, density)
    assert f0 <= model_cost(l0 * 0.95, w, density) and f0 <= model_cost(l0 * 1.05, w, density)


def test_cost_model_refuses_nonsense():
    with pytest.raises(InputError):
        cell_size(0.1, 0.0)


def test_scene_has_thesis_parameters_and_is_seeded():
    s = make_scene("uniform", n=512, seed=3)
    assert s.size == pytest.approx(100.0, rel=0.01)  # Table 5.3 rounds it to L = 100
    assert s.density == pytest.approx(0.0005)
    assert make_scene("uniform", n=512, size=100.0).size == 100.0
    again = make_scene("uniform", n=512, seed=3)
    assert np.array_equal(s.centres, again.centres)
    assert np.allclose(np.linalg.norm(s.directions, axis=1), 1.0)


def test_bodies_move_at_speed_and_stay_inside():
    s = make_scene("uniform", n=300, size=20.0, speed=0.8, seed=1)
    for _ in range(100):
        before = s.centres.copy()
        s.step()
        step = np.linalg.norm(s.centres - before, axis=1)
        assert (step <= 0.8 + 1e-9).all()
        assert np.median(step) == pytest.approx(0.8)
        assert (s.centres >= s.radii[:, None] - 1e-12).all()
        assert (s.centres <= s.size - s.radii[:, None] + 1e-12).all()


def test_clustered_scenes_stay_clustered():
    s = make_scene("sediment", n=2000, seed=2)
    for _ in range(200):
        s.step()
    assert (s.centres[:, 2] < 0.1 * s.size).mean() > 0.75
    g = make_scene("gaussian", n=2000, seed=2, clusters=3)
    u = make_scene("uniform", n=2000, seed=2)
    for _ in range(200):
        g.step()
        u.step()

    def occupied(scene):
        return len(np.unique((scene.centres // (scene.size / 10)).astype(int), axis=0))

    assert occupied(g) < 0.6 * occupied(u)  # blocks of a 10 x 10 x 10 split


def test_scene_errors():
    with pytest.raises(UnknownNameError):
        make_scene("foam")
    with pytest.raises(InputError):
        make_scene(size=1.0)
    assert side_for(2048, 0.0005) == pytest.approx(160.0)


def test_hdbc_separates_blobs_of_different_density():
    rng = np.random.default_rng(0)
    a = rng.normal(0, 1.0, (400, 3))
    b = rng.normal(0, 4.0, (400, 3)) + 60
    cl = hdbc(np.vstack([a, b]), k=8, delta=0.5, min_size=30)
    assert cl.n_clusters >= 2
    la, lb = cl.labels[:400], cl.labels[400:]
    main_a = np.bincount(la[la >= 0]).argmax()
    main_b = np.bincount(lb[lb >= 0]).argmax()
    assert main_a != main_b
    assert main_a == 0  # the denser blob is numbered first
    assert cl.mean_nd[0] < cl.mean_nd[main_b]


def test_region_growing_finds_a_dense_slab():
    edges = np.linspace(0, 100, 101)
    counts = np.full(100, 10)
    counts[40:60] = 100
    splits = grow_regions(edges, counts, threshold=0.5, max_regions=8)
    assert 40.0 in splits and 60.0 in splits
    assert len(splits) == 4
