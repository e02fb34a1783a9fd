"""Exact triangle-triangle intersection and distance: hand-made edge cases and coal on random pairs."""

from __future__ import annotations

import coal
import numpy as np
import pytest

from shared.collision.distance import tri_tri_distance_np
from shared.collision.tri_tri import tri_tri_intersect_np as hit

T0 = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def both(p, q) -> bool:
    """The answer must not depend on the argument order or the vertex order."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    answers = {hit(p, q), hit(q, p), hit(p[::-1], q), hit(p, q[[1, 2, 0]]), hit(q[[2, 0, 1]], p[::-1])}
    assert len(answers) == 1, f"order-dependent answer for {p.tolist()} / {q.tolist()}"
    return answers.pop()


def test_separated_and_crossing() -> None:
    assert not both(T0, T0 + [0, 0, 1])
    crossing = np.array([[0.2, 0.2, -1.0], [0.2, 0.2, 1.0], [0.3, -1.0, 0.0]])
    assert both(T0, crossing)
    beside = np.array([[2.0, 2.0, -1.0], [2.0, 2.0, 1.0], [3.0, 2.0, 0.0]])
    assert not both(T0, beside)


def test_piercing_edge_through_interior() -> None:
    q = np.array([[0.25, 0.25, -0.5], [0.25, 0.25, 0.5], [5.0, 5.0, 0.0]])
    assert both(T0, q)


def test_touching_at_a_vertex_counts() -> None:
    q = np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 0.0, 1.0]])  # meets T0 only at (1, 0, 0)
    assert both(T0, q)
    assert not both(T0, q + [1e-9, 0.0, 0.0])


def test_vertex_touching_the_face_interior() -> None:
    q = np.array([[0.2, 0.2, 0.0], [0.2, 0.2, 1.0], [0.5, 0.0, 1.0]])
    assert both(T0, q)
    assert not both(T0, q + [0.0, 0.0, 1e-12])


def test_shared_edge_coplanar_and_folded() -> None:
    coplanar_neighbour = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    assert both(T0, coplanar_neighbour)
    folded = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 1.0]])
    assert both(T0, folded)


def test_coplanar_cases() -> None:
    assert both(T0, T0 * 0.2 + [0.1, 0.1, 0.0])  # one inside the other
    assert both(T0, T0 + [0.5, 0.2, 0.0])  # overlapping
    assert not both(T0, T0 + [2.0, 0.0, 0.0])  # apart
    assert both(T0, T0 + [1.0, 0.0, 0.0])  # touching at a vertex
    assert both(T0, np.array([[0.5, 0.5, 0.0], [1.0, 1.0, 0.0], [0.5, 2.0, 0.0]]))  # vertex on the hypotenuse
    assert not both(T0, np.array([[0.5 + 1e-9, 0.5 + 1e-9, 0.0], [1.0, 1.0, 0.0], [0.5, 2.0, 0.0]]))
    assert not both(T0, -T0 + [-1e-12, 0.0, 0.0] + [0.0, -1e-12, 0.0])


def test_edge_lying_in_the_other_plane() -> None:
    q = np.array([[0.1, 0.1, 0.0], [0.3, 0.3, 0.0], [0.2, 0.2, 1.0]])  # edge in T0's plane, inside T0
    assert both(T0, q)
    q_out = np.array([[2.0, 2.0, 0.0], [3.0, 3.0, 0.0], [2.5, 2.5, 1.0]])  # on the plane, outside
    assert not both(T0, q_out)
    collinear_apart = np.array([[2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [2.5, 0.0, 1.0]])  # on T0's edge line
    assert not both(T0, collinear_apart)
    collinear_overlap = np.array([[0.5, 0.0, 0.0], [3.0, 0.0, 0.0], [2.5, 0.0, 1.0]])
    assert both(T0, collinear_overlap)


def test_degenerate_triangles() -> None:
    segment_through = np.array([[0.2, 0.2, -1.0], [0.2, 0.2, 1.0], [0.2, 0.2, 0.0]])  # collinear
    assert both(T0, segment_through)
    segment_beside = segment_through + [1.0, 1.0, 0.0]
    assert not both(T0, segment_beside)
    point_on = np.array([[0.2, 0.2, 0.0]] * 3)
    assert both(T0, point_on)
    assert not both(T0, point_on + [0.0, 0.0, 1e-9])
    seg_a = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    seg_b = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.5, 0.0]])
    assert both(seg_a, seg_b)
    assert not both(seg_a, seg_b + [0.0, 0.0, 1e-6])
    coplanar_segment = np.array([[0.1, 0.1, 0.0], [0.3, 0.3, 0.0], [0.2, 0.2, 0.0]])
    assert both(T0, coplanar_segment)


def test_distance_of_simple_cases() -> None:
    d, pa, pb = tri_tri_distance_np(T0, T0 + [0, 0, 0.5])
    assert d == pytest.approx(0.5)
    assert pb[2] - pa[2] == pytest.approx(0.5)
    d, pa, pb = tri_tri_distance_np(T0, np.array([[2.0, 0.0, 1.0], [2.0, 0.0, -1.0], [3.0, 0.0, 0.0]]))
    assert d == pytest.approx(1.0)
    np.testing.assert_allclose(pa, [1.0, 0.0, 0.0], atol=1e-12)
    d, _, _ = tri_tri_distance_np(T0, np.array([[0.2, 0.2, -1.0], [0.2, 0.2, 1.0], [0.3, -1.0, 0.0]]))
    assert d == 0.0


def _coal_tri(t: np.ndarray):
    m = coal.BVHModelOBBRSS()
    m.beginModel(1, 3)
    m.addVertices(np.asarray(t, float))
    m.addTriangles(np.array([[0, 1, 2]], dtype=np.int64))
    m.endModel()
    return coal.CollisionObject(m, coal.Transform3s())


def test_random_pairs_agree_with_coal() -> None:
    rng = np.random.default_rng(7)
    creq = coal.CollisionRequest()
    dreq = coal.DistanceRequest()
    n_hit = 0
    for _ in range(3000):
        p = rng.uniform(-1, 1, (3, 3))
        q = rng.uniform(-1, 1, (3, 3)) + rng.uniform(-0.8, 0.8, 3)
        a, b = _coal_tri(p), _coal_tri(q)
        cres = coal.CollisionResult()
        coal.collide(a, b, creq, cres)
        ours = hit(p, q)
        dres = coal.DistanceResult()
        coal.distance(a, b, dreq, dres)
        if cres.isCollision() != ours:
            # only a numerical tie may differ: then the distance is ~0
            assert abs(dres.min_distance) < 1e-12, (p.tolist(), q.tolist())
        n_hit += ours
        if not ours:
            d, pa, pb = tri_tri_distance_np(p, q)
            assert d == pytest.approx(dres.min_distance, abs=1e-12)
            assert np.linalg.norm(pa - pb) == pytest.approx(d, abs=1e-12)
    assert 300 < n_hit < 2700  # both kinds were exercised
