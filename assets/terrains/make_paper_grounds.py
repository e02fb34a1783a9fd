"""Write the grounds of seed 004's flat-ground and stone experiments (Tables 3, 4 and 5):

* ``flat_ground.ply``: a flat square 2 m x 2 m at z = 0, a 40 x 40 grid of 50 mm cells (3200
  triangles, so the console's red contact triangles stay local);
* ``stone.ply``: a rock, the convex hull of a flattened, seeded-perturbed ellipsoid with its base
  at z = 0 and its centre on the z axis (metres; the cell places and sizes it, docs/terrain.md: the paper
  gives no dimensions).

Run from the project root: ``.venv/bin/python assets/terrains/make_paper_grounds.py``; the test
``tests/terrain/test_paper_tables.py`` checks the committed files are what it writes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from shared.terrain.cloud import ply_bytes

HERE = Path(__file__).resolve().parent
FLAT_HALF = 1.0  # m
FLAT_CELLS = 40
#: the rock before the cell scales it: semi-axes (m) and the seed of its bumps
STONE_SEMI_AXES = (0.060, 0.045, 0.040)
STONE_SEED = 5


def flat_ground() -> tuple[np.ndarray, np.ndarray]:
    g = np.linspace(-FLAT_HALF, FLAT_HALF, FLAT_CELLS + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    v = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    k = FLAT_CELLS + 1
    i, j = np.meshgrid(np.arange(FLAT_CELLS), np.arange(FLAT_CELLS), indexing="ij")
    a = (i * k + j).ravel()
    b, c, d = a + k, a + k + 1, a + 1
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return v, faces


def stone() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(STONE_SEED)
    n = 200
    # Fibonacci sphere, radii perturbed by up to 15 % (a knobbly rock), upper half kept, flat base
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    theta = np.pi * (1 + 5**0.5) * k
    u = np.column_stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)])
    u = u[u[:, 2] > -0.2]
    pts = u * np.asarray(STONE_SEMI_AXES) * rng.uniform(0.85, 1.0, (len(u), 1))
    pts[:, 2] = np.maximum(pts[:, 2], 0.0)
    hull = ConvexHull(pts)
    used = np.unique(hull.simplices)
    remap = -np.ones(len(pts), np.int64)
    remap[used] = np.arange(len(used))
    faces = remap[hull.simplices]
    v = pts[used]
    # outward winding
    centre = v.mean(axis=0)
    tri = v[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = np.einsum("ij,ij->i", normal, tri.mean(axis=1) - centre) < 0
    faces[flip] = faces[flip][:, ::-1]
    return v, faces


def main() -> None:
    v, f = flat_ground()
    (HERE / "flat_ground.ply").write_bytes(ply_bytes(v, f, comment="teleprog flat ground 2 m x 2 m at z = 0 (m)"))
    v, f = stone()
    (HERE / "stone.ply").write_bytes(ply_bytes(v, f, comment=f"teleprog stone, convex hull, seed {STONE_SEED} (m)"))
    print(f"wrote {HERE / 'flat_ground.ply'} and {HERE / 'stone.ply'}")


if __name__ == "__main__":
    main()
