"""Grid-density filter, generator and 2.5D Delaunay triangulation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from shared.errors import InputError
from shared.terrain.filter import grid_density_filter, mean_spacing
from shared.terrain.generator import generate_lunar_terrain, generate_points, make_spec
from shared.terrain.triangulate import triangulate_25d


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(3, 600), spacing=st.floats(0.005, 0.2))
def test_filter_keeps_spacing_and_covers_dropped(seed, n, spacing):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(0, 1, (n, 3))
    pts[rng.integers(0, n, n // 4)] = pts[0]  # duplicates
    keep = grid_density_filter(pts, spacing=spacing)
    kept = pts[keep, :2]
    assert keep[0] == 0 and np.all(np.diff(keep) > 0)
    if len(kept) > 1:
        d, _ = cKDTree(kept).query(kept, k=2)
        assert d[:, 1].min() >= spacing
    # every dropped point lies within the spacing of a point kept before it
    dropped = np.setdiff1d(np.arange(n), keep)
    for i in dropped:
        earlier = kept[keep < i]
        assert np.min(np.hypot(*(earlier - pts[i, :2]).T)) < spacing


def test_filter_default_spacing_and_errors():
    _, pts = generate_lunar_terrain(n_points=20000, origin=(0, 0), size=(1, 1))
    keep = grid_density_filter(pts)
    assert 0.5 * len(pts) < len(keep) < len(pts)
    assert mean_spacing(pts) == pytest.approx(np.sqrt(1.0 / 20000), rel=0.02)
    with pytest.raises(InputError):
        grid_density_filter(pts, spacing=-1.0)
    with pytest.raises(InputError):
        grid_density_filter(np.zeros((0, 3)))


def test_generator_is_deterministic_and_seeded():
    a = generate_lunar_terrain(seed=9, n_points=5000)[1]
    b = generate_lunar_terrain(seed=9, n_points=5000)[1]
    c = generate_lunar_terrain(seed=10, n_points=5000)[1]
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    spec, pts = generate_lunar_terrain(seed=9, n_points=5000)
    assert len(spec.craters) >= 1 and len(spec.rocks) >= 1
    assert np.abs(pts[:, 2] - spec.height(pts[:, 0], pts[:, 1])).max() < 0.005  # 0.5 mm noise, 10 sigma


@pytest.fixture(scope="module")
def cloud():
    spec = make_spec(seed=21, origin=(0, 0), size=(0.5, 0.5))
    pts = generate_points(spec, 1500)
    return spec, pts[grid_density_filter(pts)]


def test_triangulation_is_delaunay(cloud):
    _, pts = cloud
    mesh = triangulate_25d(pts)
    xy = pts[:, :2]
    tri = xy[mesh.faces]
    # circumcentres; no other site strictly inside any circumcircle
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    d = 2 * (a[:, 0] * (b[:, 1] - c[:, 1]) + b[:, 0] * (c[:, 1] - a[:, 1]) + c[:, 0] * (a[:, 1] - b[:, 1]))
    sa, sb, sc = (a ** 2).sum(1), (b ** 2).sum(1), (c ** 2).sum(1)
    ux = (sa * (b[:, 1] - c[:, 1]) + sb * (c[:, 1] - a[:, 1]) + sc * (a[:, 1] - b[:, 1])) / d
    uy = (sa * (c[:, 0] - b[:, 0]) + sb * (a[:, 0] - c[:, 0]) + sc * (b[:, 0] - a[:, 0])) / d
    centre = np.stack([ux, uy], 1)
    radius = np.linalg.norm(a - centre, axis=1)
    nearest, _ = cKDTree(xy).query(centre)
    assert np.all(nearest >= radius * (1 - 1e-9))


def test_triangulation_valid_mesh_and_matches_scipy(cloud):
    spec, pts = cloud
    mesh = triangulate_25d(pts)
    ref = triangulate_25d(pts, method="scipy")
    assert {tuple(sorted(f)) for f in mesh.faces} == {tuple(sorted(f)) for f in ref.faces}
    assert np.all(mesh.normals()[:, 2] > 0)  # counter-clockwise from above
    # a planar triangulation of the hull: F = 2V - 2 - hull vertices; every edge in 1 or 2 faces
    edges = np.sort(np.concatenate([mesh.faces[:, [0, 1]], mesh.faces[:, [1, 2]], mesh.faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert set(np.unique(counts)) <= {1, 2}
    assert len(np.unique(mesh.faces)) == len(pts)
    # the surface follows the terrain it was sampled from (barycentres, within a few mm)
    centroid = pts[mesh.faces].mean(axis=1)
    err = np.abs(centroid[:, 2] - spec.height(centroid[:, 0], centroid[:, 1]))
    assert np.median(err) < 0.002


def test_triangulation_errors():
    with pytest.raises(InputError):
        triangulate_25d(np.zeros((2, 3)))
    with pytest.raises(InputError, match="unknown triangulation"):
        triangulate_25d(np.random.default_rng(0).uniform(size=(10, 3)), method="qhull3d")
