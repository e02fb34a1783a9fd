"""The rover cells' ground in the physics world: a MuJoCo height field built from the terrain mesh.

The console's terrain (``shared.terrain.cell.cell_terrain_mesh``) is a world-frame triangle mesh,
the 2.5D Delaunay triangulation of the cell's point cloud (plus, on the stone cell, a closed stone
on a flat ground). The physics world gets the same ground as one ``<hfield>``: the mesh's upper
surface sampled on a regular xy grid.

* Sampling: every triangle is rasterised onto the grid nodes its xy projection covers (barycentric
  interpolation of its corners' heights) and each node keeps the highest triangle over it, so a
  closed body on the ground (the stone) contributes its top and the ground under it is dropped.
  Nodes no triangle covers (outside the mesh's convex hull) take the height of the nearest
  covered node.
* Extent: the mesh's xy extent, cut down to the disk the arm can reach (joint 1's axis, the sum of
  the link lengths beyond it, the farthest link shape, plus ``REACH_MARGIN``): ground the arm
  cannot reach cannot touch it, and the grid's nodes go where they matter.
* Resolution: a third of the mesh's fine point spacing (its 1st-percentile edge length in xy),
  no finer than ``MIN_CELL``, and coarsened so that neither side has more than ``MAX_SIDE``
  nodes (the XML carries every node's elevation inline).

MuJoCo's conventions (XML reference, ``asset/hfield``): ``size`` is (radius_x, radius_y,
elevation_z, base_z), the grid spans [-radius_x, radius_x] x [-radius_y, radius_y] about the
geom's frame, ``ncol`` nodes along x and ``nrow`` along y; the ``elevation`` values are scaled to
0..1 (MuJoCo normalises them itself; they are written normalised), the lowest node sits at the
geom's z and the highest ``elevation_z`` above it, and a box ``base_z`` deep lies under the
lowest node; the XML lists the rows from +y down to -y (mjModel stores them bottom to top).
Each grid cell is two triangles: between the nodes the surface is piecewise linear, as the mesh is,
but on the grid's own triangles, so the two differ by up to a fraction of the grid cell times the
change of slope at the mesh's edges (and at the stone's rim, where the grid bevels a vertical
step over one cell).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
import numpy as np

#: no grid cell finer than this (m)
MIN_CELL = 1.0e-3
#: at most this many nodes along either side of the grid
MAX_SIDE = 500
#: grid cell as a fraction of the mesh's fine point spacing
SPACING_FRACTION = 1.0 / 3.0
#: margin (m) added around the arm's reach when the grid is cut down to it
REACH_MARGIN = 0.03
#: depth (m) of the solid box MuJoCo puts under the lowest node
BASE_DEPTH = 0.05
#: candidate (triangle, node) pairs rasterised at once
_CHUNK = 4_000_000


@dataclass(frozen=True)
class HeightGrid:
    """The terrain's heights on a regular grid: node (r, c) at x = x0 + c h, y = y0 + r h (world
    frame, metres); ``heights`` (nrow, ncol), row index along +y, column along +x."""

    x0: float
    y0: float
    h: float
    heights: np.ndarray

    @property
    def nrow(self) -> int:
        return int(self.heights.shape[0])

    @property
    def ncol(self) -> int:
        return int(self.heights.shape[1])

    @property
    def centre(self) -> tuple[float, float]:
        return self.x0 + 0.5 * (self.ncol - 1) * self.h, self.y0 + 0.5 * (self.nrow - 1) * self.h

    @property
    def radius(self) -> tuple[float, float]:
        return 0.5 * (self.ncol - 1) * self.h, 0.5 * (self.nrow - 1) * self.h

    def height_at(self, x, y) -> np.ndarray:
        """The grid's surface at world ``x``, ``y`` (arrays), on MuJoCo's split of each cell into
        two triangles along the diagonal from (c, r) to (c + 1, r + 1); clamped to the grid."""
        u = np.clip((np.asarray(x, dtype=float) - self.x0) / self.h, 0.0, self.ncol - 1)
        v = np.clip((np.asarray(y, dtype=float) - self.y0) / self.h, 0.0, self.nrow - 1)
        c = np.minimum(np.floor(u).astype(np.int64), self.ncol - 2)
        r = np.minimum(np.floor(v).astype(np.int64), self.nrow - 2)
        fu, fv = u - c, v - r
        H = self.heights
        z00, z10, z01, z11 = H[r, c], H[r, c + 1], H[r + 1, c], H[r + 1, c + 1]
        lower = fu >= fv  # the triangle (c, r), (c + 1, r), (c + 1, r + 1)
        return np.where(lower, z00 + fu * (z10 - z00) + fv * (z11 - z10), z00 + fv * (z01 - z00) + fu * (z11 - z01))

    def triangles(self, lo=None, hi=None) -> tuple[np.ndarray, np.ndarray]:
        """The grid's surface as triangles (vertices (V, 3), faces (F, 3), counter-clockwise from
        above), split as MuJoCo splits each cell; only the nodes within the xy window ``lo``..``hi``
        when one is given (the whole grid otherwise)."""
        c0, r0, c1, r1 = 0, 0, self.ncol - 1, self.nrow - 1
        if lo is not None:
            c0 = int(np.clip(np.floor((lo[0] - self.x0) / self.h), 0, self.ncol - 2))
            r0 = int(np.clip(np.floor((lo[1] - self.y0) / self.h), 0, self.nrow - 2))
        if hi is not None:
            c1 = int(np.clip(np.ceil((hi[0] - self.x0) / self.h), c0 + 1, self.ncol - 1))
            r1 = int(np.clip(np.ceil((hi[1] - self.y0) / self.h), r0 + 1, self.nrow - 1))
        cols, rows = np.arange(c0, c1 + 1), np.arange(r0, r1 + 1)
        X, Y = np.meshgrid(self.x0 + cols * self.h, self.y0 + rows * self.h)
        vertices = np.stack([X.ravel(), Y.ravel(), self.heights[r0:r1 + 1, c0:c1 + 1].ravel()], axis=1)
        w = len(cols)
        n00 = (np.arange(len(rows) - 1)[:, None] * w + np.arange(w - 1)[None, :]).ravel()
        n10, n01, n11 = n00 + 1, n00 + w, n00 + w + 1
        faces = np.concatenate([np.stack([n00, n10, n11], 1), np.stack([n00, n11, n01], 1)]).astype(np.int32)
        return vertices, faces


def rasterise(vertices: np.ndarray, faces: np.ndarray, x0: float, y0: float, h: float, nrow: int, ncol: int) -> np.ndarray:
    """Heights (nrow, ncol) of the highest triangle over each grid node (NaN where none is)."""
    P = np.asarray(vertices, dtype=float)[np.asarray(faces, dtype=np.int64)]  # (T, 3, 3)
    a, b, c = P[:, 0], P[:, 1], P[:, 2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    keep = np.abs(det) > 1e-18  # vertical triangles have no area in xy
    a, b, c, det = a[keep], b[keep], c[keep], det[keep]
    lo, hi = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
    eps = 1e-9
    i0 = np.clip(np.ceil((lo[:, 0] - x0) / h - eps), 0, ncol).astype(np.int64)
    i1 = np.clip(np.floor((hi[:, 0] - x0) / h + eps), -1, ncol - 1).astype(np.int64)
    j0 = np.clip(np.ceil((lo[:, 1] - y0) / h - eps), 0, nrow).astype(np.int64)
    j1 = np.clip(np.floor((hi[:, 1] - y0) / h + eps), -1, nrow - 1).astype(np.int64)
    nx, ny = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    counts = nx * ny
    out = np.full(nrow * ncol, -np.inf)
    # triangles in chunks of at most _CHUNK candidate nodes
    ends = np.cumsum(counts)
    start_t = 0
    while start_t < len(counts):
        base = ends[start_t - 1] if start_t else 0
        stop_t = max(int(np.searchsorted(ends, base + _CHUNK, side="right")), start_t + 1)
        t = np.repeat(np.arange(start_t, stop_t), counts[start_t:stop_t])
        if len(t):
            first = np.repeat(ends[start_t:stop_t] - counts[start_t:stop_t], counts[start_t:stop_t])
            k = np.arange(base, base + len(t)) - first
            gx = i0[t] + k % nx[t]
            gy = j0[t] + k // nx[t]
            px = x0 + gx * h - a[t, 0]
            py = y0 + gy * h - a[t, 1]
            l1 = (px * (c[t, 1] - a[t, 1]) - py * (c[t, 0] - a[t, 0])) / det[t]
            l2 = ((b[t, 0] - a[t, 0]) * py - (b[t, 1] - a[t, 1]) * px) / det[t]
            inside = (l1 >= -eps) & (l2 >= -eps) & (l1 + l2 <= 1.0 + eps)
            z = a[t, 2] + l1 * (b[t, 2] - a[t, 2]) + l2 * (c[t, 2] - a[t, 2])
            np.maximum.at(out, (gy * ncol + gx)[inside], z[inside])
        start_t = stop_t
    out[~np.isfinite(out)] = np.nan
    return out.reshape(nrow, ncol)


def _fill_nearest(H: np.ndarray) -> np.ndarray:
    """NaN nodes take the value of the nearest finite node along their row (rows with none, then,
    of the nearest along their column)."""
    if not np.isnan(H).any():
        return H
    if np.isnan(H).all():
        raise ValueError("no grid node lies under the terrain mesh")
    return _fill_axis(_fill_axis(H, 1), 0)


def _fill_axis(H: np.ndarray, axis: int) -> np.ndarray:
    A = H if axis == 1 else H.T
    valid = ~np.isnan(A)
    n = A.shape[1]
    idx = np.arange(n)[None, :].repeat(A.shape[0], 0)
    left = np.maximum.accumulate(np.where(valid, idx, -1), axis=1)
    right = np.minimum.accumulate(np.where(valid, idx, n)[:, ::-1], axis=1)[:, ::-1]
    use_left = (left >= 0) & ((right >= n) | (idx - left <= right - idx))
    src = np.where(use_left, left, right)
    rows = np.arange(A.shape[0])[:, None]
    out = np.where(valid, A, np.where((src >= 0) & (src < n), A[rows, np.clip(src, 0, n - 1)], np.nan))
    return out if axis == 1 else out.T


def reach_disk(cell) -> tuple[np.ndarray, float] | None:
    """Centre (xy, world) and radius of a disk holding every point the arm's moving links can
    reach: joint 1's axis, and the joints' offsets beyond it plus the farthest link shape."""
    try:
        robot = cell.robot
        model = robot.model
        world_T_base = np.asarray(cell.world_T_base, dtype=float)
        # joint 1's frame in the base frame (pinocchio's placements compose from the universe)
        base_T_j1 = np.asarray(model.jointPlacements[1].homogeneous, dtype=float)
        centre = (world_T_base @ base_T_j1)[:2, 3]
        chain = 0.0
        reach = 0.0
        for i in range(1, robot.dof + 1):
            if i > 1:
                chain += float(np.linalg.norm(np.asarray(model.jointPlacements[i].translation, dtype=float)))
            for shape in robot.shapes.get(i, ()):
                reach = max(reach, chain + _shape_extent(shape))
        tool = np.asarray(cell.flange_T_tcp, dtype=float)[:3, 3]
        reach = max(reach, chain + float(np.linalg.norm(tool)))
        return centre, reach + REACH_MARGIN
    except Exception:  # a robot without the pinocchio model: the mesh's whole extent
        return None


def _shape_extent(shape) -> float:
    """Farthest point of a link shape from its link frame's origin (a bound)."""
    centre = float(np.linalg.norm(np.asarray(shape.link_T_shape, dtype=float)[:3, 3]))
    if shape.kind == "box":
        r = 0.5 * float(np.linalg.norm(shape.size))
    elif shape.kind == "sphere":
        r = float(shape.radius)
    elif shape.kind in ("cylinder", "capsule"):
        half = 0.5 * float(shape.length)
        r = float(np.hypot(shape.radius, half)) if shape.kind == "cylinder" else half + float(shape.radius)
    else:
        r = 0.5 * float(np.linalg.norm(getattr(shape, "size", (1.0, 1.0, 1.0))))
    return centre + r


def plan_grid(vertices: np.ndarray, faces: np.ndarray, disk: tuple[np.ndarray, float] | None = None
              ) -> tuple[float, float, float, int, int]:
    """(x0, y0, h, nrow, ncol) of the grid for a mesh, cut down to ``disk`` (centre, radius)."""
    lo, hi = vertices[:, :2].min(axis=0), vertices[:, :2].max(axis=0)
    if disk is not None:
        centre, radius = disk
        lo = np.maximum(lo, centre - radius)
        hi = np.minimum(hi, centre + radius)
        if np.any(hi <= lo):  # the arm cannot reach the terrain at all: keep it whole
            lo, hi = vertices[:, :2].min(axis=0), vertices[:, :2].max(axis=0)
    P = vertices[faces]
    edges = np.concatenate([P[:, 1, :2] - P[:, 0, :2], P[:, 2, :2] - P[:, 1, :2], P[:, 0, :2] - P[:, 2, :2]])
    lengths = np.linalg.norm(edges, axis=1)
    lengths = lengths[lengths > 1e-6]
    spacing = float(np.percentile(lengths, 1.0)) if len(lengths) else float(np.max(hi - lo))
    extent = float(np.max(hi - lo))
    h = max(MIN_CELL, SPACING_FRACTION * spacing, extent / (MAX_SIDE - 1))
    ncol = int(np.ceil((hi[0] - lo[0]) / h - 1e-9)) + 1
    nrow = int(np.ceil((hi[1] - lo[1]) / h - 1e-9)) + 1
    ncol, nrow = max(ncol, 2), max(nrow, 2)
    # centre the grid on the extent (it may overhang by less than a cell each side)
    x0 = 0.5 * (lo[0] + hi[0]) - 0.5 * (ncol - 1) * h
    y0 = 0.5 * (lo[1] + hi[1]) - 0.5 * (nrow - 1) * h
    return float(x0), float(y0), float(h), nrow, ncol


def height_grid(vertices: np.ndarray, faces: np.ndarray, disk: tuple[np.ndarray, float] | None = None) -> HeightGrid:
    """The mesh's upper surface sampled on the planned grid."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    x0, y0, h, nrow, ncol = plan_grid(vertices, faces, disk)
    H = _fill_nearest(rasterise(vertices, faces, x0, y0, h, nrow, ncol))
    return HeightGrid(x0, y0, h, H)


def cell_height_grid(cell) -> HeightGrid:
    """The height grid of a terrain cell (cached on the mesh files and the poses)."""
    from shared.terrain.cell import TERRAIN_OBJECT

    obj = next(o for o in cell.objects if o.name == TERRAIN_OBJECT)
    disk = reach_disk(cell)
    key = [np.asarray(obj.world_T_object, dtype=float).round(12).tobytes()]
    for s in obj.shapes:
        if s.kind == "mesh":
            path = str(s.mesh_path)
            try:
                stamp = os.stat(path).st_mtime_ns
            except OSError:
                stamp = 0
            key.append((path, stamp, tuple(np.ravel(s.scale)), np.asarray(s.link_T_shape, float).round(12).tobytes()))
    disk_key = None if disk is None else (tuple(np.round(disk[0], 12)), round(float(disk[1]), 12))
    return _cached_grid(tuple(key), disk_key, cell)


#: height grids by mesh files and poses (the cell itself is not hashable)
_grid_cache: dict = {}


def _cached_grid(key, disk_key, cell) -> HeightGrid:
    grid = _grid_cache.get((key, disk_key))
    if grid is None:
        from shared.terrain.cell import cell_terrain_mesh

        mesh = cell_terrain_mesh(cell)
        disk = None if disk_key is None else (np.array(disk_key[0]), disk_key[1])
        grid = height_grid(mesh.vertices, mesh.faces, disk)
        if len(_grid_cache) >= 8:
            _grid_cache.pop(next(iter(_grid_cache)))
        _grid_cache[(key, disk_key)] = grid
    return grid


def _format_unit(values: np.ndarray) -> str:
    """Values in 0..1 as "0.ddddd" (1e-5 steps), space separated (vectorised: a few ms for 250k)."""
    q = np.clip(np.rint(np.asarray(values, dtype=float) * 100000.0), 0, 100000).astype(np.int64)
    buf = np.empty((len(q), 8), dtype=np.uint8)
    buf[:, 0] = np.where(q >= 100000, ord("1"), ord("0"))
    buf[:, 1] = ord(".")
    frac = np.where(q >= 100000, 0, q)
    for k in range(5):
        buf[:, 2 + k] = ord("0") + (frac // 10 ** (4 - k)) % 10
    buf[:, 7] = ord(" ")
    return buf.tobytes()[:-1].decode("ascii")


def hfield_elements(grid: HeightGrid, name: str, geom_name: str, *, friction: float, contype: int,
                    rgba: str = "0.59 0.57 0.53 1") -> tuple[str, str]:
    """(the ``<hfield>`` asset, the ``<geom>``) of a height grid."""
    H = grid.heights
    zmin, zmax = float(H.min()), float(H.max())
    span = zmax - zmin
    if span > 1e-9:
        norm = (H - zmin) / span
    else:  # flat: MuJoCo leaves the data as given, and needs elevation_z > 0
        norm = np.zeros_like(H)
        span = 1e-4
    # the XML lists the rows from +y (top) to -y
    text = _format_unit(norm[::-1].ravel())
    rx, ry = grid.radius
    cx, cy = grid.centre
    asset = (f'<hfield name="{name}" nrow="{grid.nrow}" ncol="{grid.ncol}" '
             f'size="{rx:.10g} {ry:.10g} {span:.10g} {BASE_DEPTH:.10g}" elevation="{text}"/>')
    geom = (f'<geom name="{geom_name}" type="hfield" hfield="{name}" pos="{cx:.10g} {cy:.10g} {zmin:.10g}" '
            f'contype="{contype}" conaffinity="0" group="0" friction="{friction:.6g} 0.005 0.0001" rgba="{rgba}"/>')
    return asset, geom


def terrain_geoms(cell, obj, *, friction: float, contype: int) -> tuple[list[str], list[str]]:
    """(asset elements, worldbody elements) of the terrain object ``obj`` of ``cell``: one height
    field and its geom (named ``<obj>/hfield``)."""
    grid = cell_height_grid(cell)
    color = np.asarray(getattr(obj, "color", (150, 145, 135)) or (150, 145, 135), dtype=float)[:3] / 255.0
    rgba = " ".join(f"{v:.4g}" for v in (*color, 1.0))
    asset, geom = hfield_elements(grid, f"{obj.name}_hfield", f"{obj.name}/hfield", friction=friction,
                                  contype=contype, rgba=rgba)
    return [asset], [geom]
