"""The collision descent's box test (``kernels._box_gap``): a positive answer is a true lower
bound on the distance of the triangles inside the two boxes, and it parts boxes exactly when
the distance descent's full bound (``_node_gap``, with one more axis) does without that axis."""

from __future__ import annotations

import numpy as np

from shared.collision import kernels
from shared.collision.distance import tri_tri_distance_np


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_box_gap_is_a_lower_bound_on_the_leaf_triangles_distance(model) -> None:
    nc, nax, nh, nrad, nl, nr, nts, ntc, tv = model.packed.arrays[:9]
    leaves = np.flatnonzero(nl < 0)
    rng = np.random.default_rng(7)
    C, AC = np.empty((3, 3)), np.empty((3, 3))
    parted = touching = 0
    for _ in range(3000):
        i, j = rng.choice(leaves, 2)
        R = _rotation(rng)
        # place j's box near i's so every outcome occurs
        t = nc[i] - R @ nc[j] + rng.normal(scale=0.4 * (nrad[i] + nrad[j]) + 1e-5, size=3)
        g = kernels._box_gap(nc, nax, nh, nrad, i, j, R, t)
        tri_i = tv[nts[i]]
        tri_j = tv[nts[j]] @ R.T + t
        d = tri_tri_distance_np(tri_i, tri_j)[0]
        full = kernels._node_gap(nc, nax, nh, nrad, i, j, R, t, C, AC, 0.0, True)
        assert g >= 0.0
        if g > 0.0:
            parted += 1
            assert g <= d + 1e-12
            assert full > 0.0  # whatever this test parts, the full bound parts too
        else:
            touching += 1
    assert parted > 300 and touching > 300
