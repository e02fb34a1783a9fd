"""Convex pieces and GJK: certification refuses what is not a closed convex surface, GJK's
distance and witness points equal the brute-force triangle answer, and a scene whose solids
nest (surfaces apart, one inside the other) still gets the surface distance."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from numba import njit
from scipy.optimize import linprog

from shared.collision import kernels
from shared.collision.convex import convex_piece, convex_pieces
from shared.collision.distance import tri_tri_dist2
from shared.collision.gjk import APART, OVERLAP, PRUNED, gjk_distance
from shared.collision.mesh_model import body_mesh_from_arrays
from shared.collision.scene import SceneModel, _body
from shared.spatial import make_transform


def _shapes() -> dict[str, trimesh.Trimesh]:
    return {
        "box": trimesh.creation.box((0.3, 0.1, 0.05)),
        "cylinder": trimesh.creation.cylinder(radius=0.04, height=0.2, sections=24),
        "capsule": trimesh.creation.capsule(height=0.2, radius=0.03, count=(16, 16)),
        "sphere": trimesh.creation.icosphere(subdivisions=2, radius=0.05),
        "tetra": trimesh.Trimesh([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]),
    }


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def test_primitive_shapes_are_certified_with_their_hull_vertices() -> None:
    for name, mesh in _shapes().items():
        piece = convex_piece(np.asarray(mesh.vertices), np.asarray(mesh.faces))
        assert piece is not None, name
        pts, edges = piece
        assert len(pts) == len(mesh.convex_hull.vertices), name
        # Euler: a triangulated convex polyhedron has 3V - 6 edges
        assert len(edges) == 3 * len(pts) - 6, name


def test_open_inconsistent_and_concave_meshes_are_refused() -> None:
    box = trimesh.creation.box((0.1, 0.1, 0.1))
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    assert convex_piece(v, f[1:]) is None  # a face missing: open
    flipped = f.copy()
    flipped[0] = flipped[0, ::-1]
    assert convex_piece(v, flipped) is None  # one face wound the other way
    dented = v.copy()
    dented[0] *= 0.2  # a corner pushed towards the centre: concave
    assert convex_piece(dented, f) is None
    doubled = np.vstack([f, f])  # every edge in four faces
    assert convex_piece(v, doubled) is None
    # a body is pieced only when every piece is certified
    assert convex_pieces(v, f, [(0, 12)]) is not None
    assert convex_pieces(dented, np.vstack([f, f + 0]), [(0, 12), (12, 24)]) is None


@njit(cache=False)
def _brute_dist2(ta, tb):
    best = np.inf
    for i in range(ta.shape[0]):
        p0 = (ta[i, 0, 0], ta[i, 0, 1], ta[i, 0, 2])
        p1 = (ta[i, 1, 0], ta[i, 1, 1], ta[i, 1, 2])
        p2 = (ta[i, 2, 0], ta[i, 2, 1], ta[i, 2, 2])
        for j in range(tb.shape[0]):
            q0 = (tb[j, 0, 0], tb[j, 0, 1], tb[j, 0, 2])
            q1 = (tb[j, 1, 0], tb[j, 1, 1], tb[j, 1, 2])
            q2 = (tb[j, 2, 0], tb[j, 2, 1], tb[j, 2, 2])
            d2, _, _ = tri_tri_dist2(p0, p1, p2, q0, q1, q2)
            best = min(best, d2)
    return best


def _brute(va: np.ndarray, fa: np.ndarray, vb: np.ndarray, fb: np.ndarray) -> float:
    """Least distance over every triangle pair (exact for surfaces that do not cross)."""
    return float(np.sqrt(_brute_dist2(np.ascontiguousarray(va[fa]), np.ascontiguousarray(vb[fb]))))


def _hulls_meet(va: np.ndarray, vb: np.ndarray) -> bool:
    """Independent of GJK: is some convex combination of ``va`` one of ``vb`` (an LP)?"""
    na, nb = len(va), len(vb)
    a_eq = np.zeros((5, na + nb))
    a_eq[:3, :na] = va.T
    a_eq[:3, na:] = -vb.T
    a_eq[3, :na] = 1.0
    a_eq[4, na:] = 1.0
    res = linprog(np.zeros(na + nb), A_eq=a_eq, b_eq=[0, 0, 0, 1, 1], bounds=(0, None), method="highs")
    return res.status == 0


@pytest.mark.parametrize("seed", [0, 1])
def test_gjk_equals_the_triangle_distance_on_random_poses(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shapes = list(_shapes().values())
    S, SI, lam = np.empty((8, 9)), np.empty((8, 2), dtype=np.int64), np.empty(8)
    counts = {APART: 0, OVERLAP: 0, PRUNED: 0}
    for _ in range(150):
        ma, mb = shapes[rng.integers(len(shapes))], shapes[rng.integers(len(shapes))]
        pa = convex_pieces(np.asarray(ma.vertices), np.asarray(ma.faces), [(0, len(ma.faces))])
        pb = convex_pieces(np.asarray(mb.vertices), np.asarray(mb.faces), [(0, len(mb.faces))])
        V = np.vstack([pa.vertices, pb.vertices])
        adj_start = np.concatenate([pa.adj_start, pb.adj_start[1:] + len(pa.adj)])
        adj = np.concatenate([pa.adj, pb.adj + len(pa.vertices)])
        R = _random_rotation(rng)
        t = rng.uniform(-0.25, 0.25, 3)
        vb = np.asarray(mb.vertices) @ R.T + t
        meet = _hulls_meet(np.asarray(ma.vertices), vb)
        hint = t - pa.center[0]
        status, d, x, y = gjk_distance(V, adj_start, adj, 0, len(pa.vertices), len(pa.vertices), len(pb.vertices),
                                       R, t, np.inf, S, SI, lam, hint)
        counts[status] += 1
        if status == APART:
            assert not meet
            exact = _brute(np.asarray(ma.vertices), np.asarray(ma.faces), vb, np.asarray(mb.faces))
            assert d == pytest.approx(exact, abs=1e-12)
            assert np.linalg.norm(np.subtract(x, y)) == pytest.approx(d, abs=1e-12)
        else:
            assert status == OVERLAP and meet
        if status == APART and exact > 0.01:
            # bounded by an upper limit below the distance: pruned, never a wrong answer
            s2, d2, _, _ = gjk_distance(V, adj_start, adj, 0, len(pa.vertices), len(pa.vertices), len(pb.vertices),
                                        R, t, exact * 0.5, S, SI, lam, hint)
            assert s2 == PRUNED and d2 >= exact * 0.5 - 1e-12
    assert counts[APART] > 50 and counts[OVERLAP] > 5


def _two_body_scene(outer: trimesh.Trimesh, inner: trimesh.Trimesh) -> SceneModel:
    bodies = [
        _body("outer", "object", 0, body_mesh_from_arrays("outer", np.asarray(outer.vertices), np.asarray(outer.faces)), 1),
        _body("inner", "object", 1, body_mesh_from_arrays("inner", np.asarray(inner.vertices), np.asarray(inner.faces)), 1),
    ]
    return SceneModel(bodies, [(0, 1)])


def test_nested_solids_fall_back_to_the_surface_distance() -> None:
    outer = trimesh.creation.box((0.4, 0.4, 0.4))
    inner = trimesh.creation.box((0.1, 0.1, 0.1))
    model = _two_body_scene(outer, inner)
    assert all(b.pieces is not None for b in model.bodies)
    poses = np.stack([np.eye(4), make_transform(translation=np.array([0.05, 0.0, 0.0]))])
    data = model.new_data()
    report = model.check_world(poses, data=data)
    # inside, 0.2 - (0.05 + 0.05) = 0.1 m from the outer box's +x wall
    assert not report.colliding
    assert report.distance("outer", "inner").distance == pytest.approx(0.1, abs=1e-12)
    assert data.stats[kernels.ST_GJK_FALLBACK] == 1
    # moved outside: GJK answers, with witness points on both surfaces
    poses[1] = make_transform(translation=np.array([0.5, 0.0, 0.0]))
    far = model.check_world(poses, data=data).distance("outer", "inner")
    assert far.distance == pytest.approx(0.25, abs=1e-12)
    assert far.point_a[0] == pytest.approx(0.2) and far.point_b[0] == pytest.approx(0.45)
    assert data.stats[kernels.ST_GJK_FALLBACK] == 1 and data.stats[kernels.ST_GJK_PIECES] >= 2


def test_scene_distances_match_the_triangle_descent_on_the_default_cell(cell, model) -> None:
    """Every pair of the peg-in-hole cell, GJK against the tree descent (pieces withheld)."""
    from shared.collision.scene import Body

    plain = SceneModel(
        [Body(b.name, b.kind, b.index, b.mesh, b.tree, None) for b in model.bodies],
        [tuple(p) for p in model.pairs], model.robot, model.world_T_base, model.default_object_poses,
        resting=model.resting_pairs,
    )
    assert all(b.pieces is not None for b in model.bodies)
    rng = np.random.default_rng(3)
    lo, hi = cell.robot.lower, cell.robot.upper
    for _ in range(40):
        q = rng.uniform(lo, hi)
        a = model.check(q)
        b = plain.check(q)
        for key, pd in b.distances.items():
            got = a.distances[key]
            assert got.distance == pytest.approx(pd.distance, abs=1e-12), key
            if pd.distance > 0:
                np.testing.assert_allclose(np.linalg.norm(got.point_a - got.point_b), pd.distance, atol=1e-12)
