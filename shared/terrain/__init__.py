"""Terrain for the lunar-rover cell (seed 004): point clouds, 2.5D Delaunay triangulation, the
multi-way AABB tree over the triangles, the paper's virtual-sensor check beside an exact
arm-to-terrain distance, and instrument placement.

Modules: ``cloud`` (loading and checks), ``filter`` (grid-density filter), ``generator``
(seeded synthetic lunar terrain), ``triangulate`` (2.5D Delaunay), ``tree`` (multi-way AABB
tree and its numba queries), ``gjk`` (convex shape to triangle distance), ``arm`` (the arm's
link geometry and virtual sensors), ``checks`` (both checks for one arm configuration),
``placement`` (instrument placement and its statement program), ``cell`` (terrain of a cell).
"""


def warm_up() -> None:
    """Compile the terrain's numba kernels once (all ``cache=True``: numba keeps them in
    ``__pycache__`` beside the sources, and later processes load them): the grid-density filter
    on a small generated cloud, then the rover terrain cell's exact check, virtual sensors and
    contact triangles. ``scripts/setup`` calls it, so no test or console compiles them."""
    from shared.cells.loader import load_cell
    from shared.paths import ASSETS_DIR
    from shared.terrain.cell import load_cell_terrain
    from shared.terrain.filter import grid_density_filter
    from shared.terrain.generator import generate_points, make_spec

    grid_density_filter(generate_points(make_spec(seed=11, origin=(0.2, -0.8), size=(1.2, 1.2)), 2000))
    cell = load_cell(ASSETS_DIR / "cells" / "rover_terrain.toml")
    checker = load_cell_terrain(cell).checker
    checker.exact_check(cell.q_home, per_shape=True)
    checker.sensor_check(cell.q_home)
    checker.contact_triangles(cell.q_home, eps=1.0)  # a wide margin: the queries find triangles
