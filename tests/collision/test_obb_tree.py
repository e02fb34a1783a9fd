"""OBB fit (covariance, longest-axis mean split) and the tree's containment invariants."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shared.collision.obb_tree import build_obb_tree, covariance_axes, fit_obb
from shared.spatial import rpy_to_matrix


def _box_tris(extents, rotation=np.eye(3), offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    m = trimesh.creation.box(extents=extents)
    v = m.vertices @ rotation.T + np.asarray(offset)
    return v[m.faces]


@pytest.mark.parametrize("extents", [(0.3, 0.2, 0.1), (0.02, 0.02, 0.08), (0.1, 0.1, 0.1)])
@pytest.mark.parametrize("rpy", [(0, 0, 0), (0.3, -0.7, 1.1), (np.pi / 4, 0, 0), (0, 0, np.pi / 4)])
def test_fit_on_axis_aligned_and_rotated_boxes_is_the_box(extents, rpy) -> None:
    rot = rpy_to_matrix(np.array(rpy, dtype=float))
    tris = _box_tris(extents, rot, (0.5, -0.2, 0.3))
    center, axes, half = fit_obb(tris)
    np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-12)
    assert np.linalg.det(axes) == pytest.approx(1.0)
    np.testing.assert_allclose(center, [0.5, -0.2, 0.3], atol=1e-12)
    np.testing.assert_allclose(np.sort(half * 2), np.sort(extents), atol=1e-9)
    # every box axis is parallel to one of the fitted axes
    cos = np.abs(rot.T @ axes)
    np.testing.assert_allclose(np.sort(cos.max(axis=1)), [1.0, 1.0, 1.0], atol=1e-9)


def test_covariance_axes_follow_an_elongated_box() -> None:
    rot = rpy_to_matrix(np.array([0.2, 0.5, -0.4]))
    w, v = covariance_axes(_box_tris((1.0, 0.2, 0.05), rot))
    assert w[2] > w[1] > w[0]
    assert abs(v[:, 2] @ rot[:, 0]) == pytest.approx(1.0, abs=1e-9)  # largest spread: box x


def _check_tree(tree, tris_all: np.ndarray) -> None:
    n = tree.n_nodes
    seen = []
    for i in range(n):
        # every triangle under the node is inside its box and its sphere
        under = _tris_under(tree, i)
        pts = tree.tris[under].reshape(-1, 3)
        local = (pts - tree.center[i]) @ tree.axes[i]
        assert np.all(np.abs(local) <= tree.half[i] + 1e-12)
        assert np.all(np.linalg.norm(pts - tree.center[i], axis=1) <= tree.radius[i] + 1e-12)
        if tree.left[i] < 0:
            seen.extend(tree.tri_ids[tree.tri_start[i]: tree.tri_start[i] + tree.tri_count[i]])
        else:
            assert tree.tri_count[i] == 0
    assert sorted(seen) == list(range(len(tris_all)))  # each triangle in exactly one leaf
    np.testing.assert_array_equal(tree.tris, tris_all[tree.tri_ids])


def test_tree_invariants_on_capsule_and_box() -> None:
    for mesh in (trimesh.creation.capsule(height=0.4, radius=0.05, count=[12, 12]), trimesh.creation.box(extents=(0.1, 0.2, 0.3))):
        tree = build_obb_tree(mesh.vertices, mesh.faces)
        _check_tree(tree, mesh.vertices[mesh.faces])
        assert tree.depth < 40
        assert np.all(tree.tri_count[tree.left < 0] == 1)  # split until one triangle per leaf
        v = mesh.vertices
        assert np.all(np.linalg.norm(v - tree.sphere_center, axis=1) <= tree.sphere_radius)
        lo, hi = v.min(axis=0), v.max(axis=0)
        np.testing.assert_allclose(tree.hull_vertices.min(axis=0), lo)
        np.testing.assert_allclose(tree.hull_vertices.max(axis=0), hi)


def test_split_is_at_the_vertex_mean_along_the_longest_axis() -> None:
    mesh = trimesh.creation.box(extents=(1.0, 0.1, 0.1))
    tree = build_obb_tree(mesh.vertices, mesh.faces)
    root_long = tree.axes[0][:, int(np.argmax(tree.half[0]))]
    tris = mesh.vertices[mesh.faces]
    mean = tris.reshape(-1, 3).mean(axis=0)
    for child, sign in ((tree.left[0], -1), (tree.right[0], 1)):
        stack, under = [child], []
        while stack:
            k = stack.pop()
            if tree.left[k] < 0:
                under.extend(tree.tri_ids[tree.tri_start[k]: tree.tri_start[k] + tree.tri_count[k]])
            else:
                stack += [tree.left[k], tree.right[k]]
        side = (tris[under].mean(axis=1) - mean) @ root_long
        assert np.all(side * sign >= 0)


def test_unsplittable_node_becomes_a_leaf() -> None:
    # three copies of one triangle: no plane separates their centroids
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    tree = build_obb_tree(np.vstack([v, v, v]), np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8]]))
    assert tree.n_nodes == 1 and tree.tri_count[0] == 3


def _tris_under(tree, i: int) -> list[int]:
    stack, under = [i], []
    while stack:
        k = stack.pop()
        if tree.left[k] < 0:
            under.extend(range(tree.tri_start[k], tree.tri_start[k] + tree.tri_count[k]))
        else:
            stack += [tree.left[k], tree.right[k]]
    return under


def test_swept_rectangles_contain_their_nodes() -> None:
    from shared.collision.obb_tree import swept_rectangles

    mesh = trimesh.creation.capsule(height=0.4, radius=0.05, count=[12, 12])
    tree = build_obb_tree(mesh.vertices, mesh.faces)
    rs = swept_rectangles(tree.axes, tree.half)
    for i in range(tree.n_nodes):
        u, v, w, (a, b, r) = rs[i, 0:3], rs[i, 3:6], rs[i, 6:9], rs[i, 9:12]
        assert a >= b >= r >= 0.0
        np.testing.assert_allclose(np.array([u, v, w]) @ np.array([u, v, w]).T, np.eye(3), atol=1e-12)
        d = tree.tris[_tris_under(tree, i)].reshape(-1, 3) - tree.center[i]
        s, t = np.clip(d @ u, -a, a), np.clip(d @ v, -b, b)
        gap = np.linalg.norm(d - s[:, None] * u - t[:, None] * v, axis=1)
        assert np.all(gap <= r + 1e-12)  # every vertex within the radius of the rectangle
    leaves = tree.left < 0
    assert np.all(rs[leaves, 11] < 1e-9)  # a leaf triangle is flat: its rectangle is tight


def test_rectangle_bound_never_exceeds_the_true_distance() -> None:
    """``kernels._rect_gap`` is a lower bound on the distance between the contents of two
    nodes (the distance descent prunes with it): checked against the exact triangle distance
    for node pairs of two meshes in random relative poses, where it must also be informative."""
    from shared.collision import kernels
    from shared.collision.distance import tri_tri_dist2
    from shared.collision.obb_tree import swept_rectangles
    from shared.collision.tri_tri import tri_tri_intersect

    def exact(p, q) -> float:
        p, q = tuple(map(tuple, p)), tuple(map(tuple, q))
        return 0.0 if tri_tri_intersect(*p, *q) else float(np.sqrt(tri_tri_dist2(*p, *q)[0]))

    ma = trimesh.creation.capsule(height=0.3, radius=0.05, count=[10, 10])
    mb = trimesh.creation.cylinder(radius=0.04, height=0.2, sections=16)
    ta, tb = build_obb_tree(ma.vertices, ma.faces), build_obb_tree(mb.vertices, mb.faces)
    ra, rb = swept_rectangles(ta.axes, ta.half), swept_rectangles(tb.axes, tb.half)
    nc = np.vstack([ta.center, tb.center])
    rs = np.vstack([ra, rb])
    off = ta.n_nodes
    rng = np.random.default_rng(3)
    informative = 0
    for _ in range(40):
        R = rpy_to_matrix(rng.uniform(-np.pi, np.pi, 3))
        t = rng.uniform(-0.25, 0.25, 3)
        for _ in range(20):
            i, j = int(rng.integers(ta.n_nodes)), int(rng.integers(tb.n_nodes))
            g = kernels._rect_gap(nc, rs, i, off + j, R, t, np.inf)
            assert g == -np.inf  # nothing can reach an infinite threshold: no work done
            g = kernels._rect_gap(nc, rs, i, off + j, R, t, 0.0)
            if g == -np.inf:
                continue
            pa = ta.tris[_tris_under(ta, i)]
            pb = tb.tris[_tris_under(tb, j)] @ R.T + t
            d = min(exact(p, q) for p in pa for q in pb)
            assert g <= d + 1e-12
            informative += g > 0.0
    assert informative > 50


@pytest.mark.parametrize("make", [
    lambda: trimesh.creation.capsule(height=0.4, radius=0.05, count=[16, 16]),
    lambda: trimesh.creation.icosphere(subdivisions=3, radius=0.1),
    lambda: trimesh.creation.cylinder(radius=0.04, height=0.3, sections=48),
])
def test_the_compiled_build_is_the_python_reference(make) -> None:
    """The numba build (``obb_build``) runs the reference's algorithm: as many nodes, the same
    root, boxes as tight, and every containment invariant. Symmetric meshes are full of ties (a
    centroid on the split plane falls either side when the vertex mean is summed in another
    order; a sphere's candidate boxes are equal), so the trees may differ in which of equals they
    took, never in quality."""
    mesh = make()
    fast = build_obb_tree(mesh.vertices, mesh.faces)
    slow = build_obb_tree(mesh.vertices, mesh.faces, compiled=False)
    _check_tree(fast, mesh.vertices[mesh.faces])
    assert fast.n_nodes == slow.n_nodes and abs(fast.depth - slow.depth) <= 1
    np.testing.assert_allclose(fast.center[0], slow.center[0], atol=1e-9)
    # a sphere's candidate boxes tie: the one kept may differ, its volume may not
    assert np.prod(fast.half[0]) == pytest.approx(np.prod(slow.half[0]), rel=1e-3)
    volume = lambda t: float(np.prod(2.0 * t.half, axis=1).sum())  # noqa: E731
    assert volume(fast) <= 1.02 * volume(slow)  # never looser (on a sphere the choice among ties may be tighter)
