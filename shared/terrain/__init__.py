"""Terrain for the lunar-rover cell (seed 004): point clouds, 2.5D Delaunay triangulation, the
multi-way AABB tree over the triangles, the paper's virtual-sensor check beside an exact
arm-to-terrain distance, and instrument placement.

Modules: ``cloud`` (loading and checks), ``filter`` (grid-density filter), ``generator``
(seeded synthetic lunar terrain), ``triangulate`` (2.5D Delaunay), ``tree`` (multi-way AABB
tree and its numba queries), ``gjk`` (convex shape to triangle distance), ``arm`` (the arm's
link geometry and virtual sensors), ``checks`` (both checks for one arm configuration),
``placement`` (instrument placement and its statement program), ``cell`` (terrain of a cell).
"""
