"""The multi-way AABB tree against brute force, and the exact distance (b) against coal."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from shared.terrain.gjk import BOX, CAPSULE, CYLINDER, SPHERE, make_workspace, shape_triangle_distance
from shared.terrain.reference import coal_min_distance, coal_shapes, coal_terrain
from shared.terrain.tree import build_tree, query_shapes, ray_hits, shape_triangles_within


def _random_shape(rng, tree):
    kind = int(rng.integers(0, 4))
    par = np.array([rng.uniform(0.01, 0.05), rng.uniform(0.0, 0.1), *rng.uniform(0.01, 0.06, 3)])
    R = Rotation.random(random_state=int(rng.integers(1 << 30))).as_matrix()
    lo, hi = tree.lo[0], tree.hi[0]
    t = np.array([rng.uniform(lo[0], hi[0]), rng.uniform(lo[1], hi[1]), rng.uniform(lo[2] - 0.05, hi[2] + 0.2)])
    return kind, R, t, par


def _brute(tree, kind, R, t, par):
    ws = make_workspace()
    pa, pb = np.empty(3), np.empty(3)
    tris = tree.vertices[tree.faces]
    return np.array([shape_triangle_distance(kind, R, t, par, tri, pa, pb, np.inf, ws) for tri in tris])


@pytest.mark.parametrize("branching, leaf", [(8, 4), (2, 1), (16, 16)])
def test_tree_distance_equals_brute_force(small_mesh, branching, leaf):
    tree = build_tree(small_mesh, branching, leaf)
    rng = np.random.default_rng(branching * 100 + leaf)
    for _ in range(25):
        kind, R, t, par = _random_shape(rng, tree)
        brute = _brute(tree, kind, R, t, par)
        out_d, pa, pb = np.empty(1), np.zeros((1, 3)), np.zeros((1, 3))
        pos, shp = np.empty(1, np.int64), np.empty(1, np.int64)
        query_shapes(np.array([kind]), R[None], t[None], par[None], np.zeros(1, np.int64), 1, *tree.arrays(), np.inf,
                     out_d, pa, pb, pos, shp)
        assert out_d[0] == pytest.approx(max(brute.min(), 0.0), abs=1e-9)  # 0 on contact
        # the witness points realise the distance (when separated) and lie on the reported triangle
        if out_d[0] > 0:
            assert np.linalg.norm(pa[0] - pb[0]) == pytest.approx(out_d[0], abs=1e-8)
            tri = tree.vertices[tree.faces[pos[0]]]
            n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
            assert abs(np.dot(pb[0] - tri[0], n / np.linalg.norm(n))) < 1e-9
        eps = max(out_d[0], 0.0) + 0.01
        found = np.empty(100_000, np.int64)
        k = shape_triangles_within(kind, R, t, par, eps, *tree.arrays(), found)
        assert set(found[:k]) == set(np.flatnonzero(brute <= eps))


def test_ray_hits_equal_brute_force(small_tree):
    tree = small_tree
    rng = np.random.default_rng(3)
    n = 200
    origins = np.stack([rng.uniform(tree.lo[0, 0], tree.hi[0, 0], n), rng.uniform(tree.lo[0, 1], tree.hi[0, 1], n),
                        rng.uniform(tree.hi[0, 2], tree.hi[0, 2] + 0.3, n)], 1)
    dirs = rng.normal(size=(n, 3))
    dirs[:, 2] = -np.abs(dirs[:, 2])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    t, pos = np.empty(n), np.empty(n, np.int64)
    ray_hits(origins, dirs, 5.0, *tree.arrays(), t, pos)
    tris = tree.vertices[tree.faces]
    for i in range(0, n, 4):  # brute force: Möller-Trumbore over every triangle in numpy
        e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
        p = np.cross(dirs[i], e2)
        det = np.einsum("ij,ij->i", e1, p)
        s = origins[i] - tris[:, 0]
        u = np.einsum("ij,ij->i", s, p) / det
        qv = np.cross(s, e1)
        v = (qv @ dirs[i]) / det
        tt = np.einsum("ij,ij->i", e2, qv) / det
        ok = (u >= 0) & (v >= 0) & (u + v <= 1) & (tt >= 0)
        expected = tt[ok].min() if ok.any() else np.inf
        assert t[i] == pytest.approx(expected, abs=1e-9)


def test_exact_distance_matches_coal(cell_terrain, random_q):
    """(b) against coal's BVH distance on the same triangles and primitives: within 0.01 mm."""
    checker, arm = cell_terrain.checker, cell_terrain.arm
    terrain = coal_terrain(cell_terrain.mesh)
    shapes = coal_shapes(arm)
    compared = 0
    for q in random_q:
        ours = checker.exact_check(q)
        Rs, ts = arm.shape_poses(checker.world_T_base, q)
        ref, p_arm, p_terrain = coal_min_distance(terrain, shapes, Rs, ts)
        if ref <= 0 or ours.distance <= 0:
            assert ref <= 1e-5 and ours.distance <= 1e-5  # both see the contact
            continue
        compared += 1
        assert ours.distance == pytest.approx(ref, abs=1e-5)
        assert np.linalg.norm(ours.world_p_arm - ours.world_p_terrain) == pytest.approx(ours.distance, abs=1e-8)
    assert compared >= 30


def test_per_shape_and_contact_triangles(cell_terrain, cell):
    checker = cell_terrain.checker
    q = np.radians([-30.0, -10.0, -60.0])
    rep = checker.exact_check(q, per_shape=True)
    assert min(rep.per_shape.values()) == pytest.approx(rep.distance)
    assert rep.shape == min(rep.per_shape, key=rep.per_shape.get)
    # push the arm into the ground: contact, and the contact triangles include the nearest one
    base_T_world = np.linalg.inv(cell.world_T_base)
    from shared.robots.ik import solve_ik
    from shared.terrain.placement import terrain_point_at

    ground = terrain_point_at(checker, 0.70, 0.0)
    q_in = solve_ik(cell.robot, position=(base_T_world @ np.append(ground - [0, 0, 0.02], 1))[:3])[0]
    hit = checker.exact_check(q_in)
    assert hit.in_collision and hit.distance <= 0
    assert len(hit.contact_triangles) > 0
    assert checker.sensor_check(q_in).in_collision
