"""Terrain point clouds: load PLY (ascii or binary), XYZ/CSV/TXT and NPY files into an (N, 3)
array in metres, and check that a cloud is 2.5D (one height per ground position) over the
chosen ground plane.

Every problem is a ``FileFormatError`` (file) or ``InputError`` (array) with one line saying what
is wrong and where, because a rover operator feeding a camera's cloud must know at once whether
the file, its units or its up axis is at fault.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from shared.errors import FileFormatError, InputError

#: file name endings the loader knows
CLOUD_SUFFIXES = (".ply", ".xyz", ".csv", ".txt", ".npy")
#: slope (deg) above which two points at nearly the same ground position count as an overhang
MAX_SLOPE_DEG = 84.0
#: fraction of occupied ground cells allowed to hold an overhang before the cloud is refused
MAX_OVERHANG_FRACTION = 0.02
_UP_AXES = {"x": 0, "y": 1, "z": 2}
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


@dataclass(frozen=True)
class PointCloud:
    """A terrain cloud in the terrain frame (z up), metres; ``source`` names where it came from."""

    points: np.ndarray  # (N, 3) float64
    source: str = "(array)"

    def __len__(self) -> int:
        return int(self.points.shape[0])


def up_transform(up: str) -> np.ndarray:
    """Rotation (3, 3) taking file coordinates with ``up`` ('x', 'y', 'z', optionally signed
    '-y') to the terrain frame (z up), keeping the frame right-handed."""
    sign = -1.0 if up.startswith("-") else 1.0
    axis = up.lstrip("+-")
    if axis not in _UP_AXES:
        raise InputError(f"up axis {up!r} is not one of x, y, z, -x, -y, -z")
    i = _UP_AXES[axis]
    # cyclic permutation: (i+1, i+2, i) -> (x, y, z) keeps handedness; a negative up flips x too
    rot = np.zeros((3, 3))
    rot[0, (i + 1) % 3] = sign
    rot[1, (i + 2) % 3] = 1.0
    rot[2, i] = sign
    return rot


def _ply_header(raw: bytes, path: Path) -> tuple[str, int, list[tuple[str, int, list]]]:
    """Format, offset of the body and the elements (name, count, properties) of a PLY file."""
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise FileFormatError(path, "not a PLY file (no 'ply' magic or no 'end_header')")
    body_start = raw.index(b"\n", end) + 1
    lines = raw[:end].decode("ascii", errors="replace").splitlines()
    fmt = ""
    elements: list[tuple[str, int, list]] = []
    for line in lines[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            fmt = words[1] if len(words) > 1 else ""
        elif words[0] == "element" and len(words) == 3:
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements:
            elements[-1][2].append(words[1:])
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise FileFormatError(path, f"unknown PLY format {fmt!r}", "format")
    vertex = [e for e in elements if e[0] == "vertex"]
    if not vertex:
        raise FileFormatError(path, "PLY has no 'vertex' element", "element vertex")
    return fmt, body_start, elements


def read_ply(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Vertices (N, 3) and, if the file has them, triangle faces (M, 3) of a PLY file."""
    raw = path.read_bytes()
    fmt, pos, elements = _ply_header(raw, path)
    endian = ">" if fmt == "binary_big_endian" else "<"
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    text_rows: list[str] | None = None
    if fmt == "ascii":
        text_rows = raw[pos:].decode("ascii", errors="replace").split("\n")
        row = 0
    for name, count, props in elements:
        is_list = any(p[0] == "list" for p in props)
        if fmt == "ascii":
            rows = [r for r in text_rows[row:row + count]]
            row += count
            if len(rows) < count or (count and not rows[-1].strip()):
                raise FileFormatError(path, f"PLY ends before its {count} '{name}' rows", f"element {name}")
            if name == "vertex":
                names = [p[-1] for p in props]
                if not all(a in names for a in "xyz"):
                    raise FileFormatError(path, "PLY vertex has no x, y, z properties", "element vertex")
                try:
                    table = np.array([r.split()[: len(names)] for r in rows], dtype=float).reshape(count, len(names))
                except ValueError:
                    raise FileFormatError(path, "PLY vertex rows hold non-numbers or too few values", "element vertex") from None
                vertices = table[:, [names.index(a) for a in "xyz"]]
            elif name == "face" and is_list:
                try:
                    lists = [[int(v) for v in r.split()] for r in rows]
                except ValueError:
                    raise FileFormatError(path, "PLY face rows hold non-integers", "element face") from None
                tris = [lst[1:4] for lst in lists if lst and lst[0] == 3 and len(lst) >= 4]
                if len(tris) != len(lists):
                    raise FileFormatError(path, "PLY faces must all be triangles", "element face")
                faces = np.array(tris, dtype=np.int64).reshape(-1, 3)
            continue
        if not is_list:
            dtype = np.dtype([(p[-1], endian + _PLY_TYPES.get(p[0], "f4")) for p in props])
            nbytes = dtype.itemsize * count
            if pos + nbytes > len(raw):
                raise FileFormatError(path, f"PLY ends before its {count} '{name}' records", f"element {name}")
            table = np.frombuffer(raw, dtype=dtype, count=count, offset=pos)
            pos += nbytes
            if name == "vertex":
                if not all(a in dtype.names for a in "xyz"):
                    raise FileFormatError(path, "PLY vertex has no x, y, z properties", "element vertex")
                vertices = np.stack([table[a].astype(float) for a in "xyz"], axis=1)
            continue
        # binary list element: only 'face' with a single list property of triangles is supported
        if len(props) != 1 or name != "face":
            raise FileFormatError(path, f"PLY element {name!r} with list properties is not supported", f"element {name}")
        _, count_t, index_t, _ = props[0]
        rec = np.dtype([("n", endian + _PLY_TYPES[count_t]), ("v", endian + _PLY_TYPES[index_t], (3,))])
        nbytes = rec.itemsize * count
        if pos + nbytes > len(raw):
            raise FileFormatError(path, f"PLY ends before its {count} faces", "element face")
        table = np.frombuffer(raw, dtype=rec, count=count, offset=pos)
        if count and np.any(table["n"] != 3):
            raise FileFormatError(path, "PLY faces must all be triangles", "element face")
        faces = table["v"].astype(np.int64)
        pos += nbytes
    assert vertices is not None
    return vertices, faces


def ply_bytes(vertices: np.ndarray, faces: np.ndarray | None = None, comment: str = "") -> bytes:
    """Binary little-endian PLY with float32 vertices and, if given, int32 triangle faces (the
    caller writes the bytes: ``shared`` reads files but does not write them)."""
    vertices = np.asarray(vertices, dtype="<f4")
    header = ["ply", "format binary_little_endian 1.0"]
    if comment:
        header.append(f"comment {comment}")
    header += [f"element vertex {len(vertices)}", "property float x", "property float y", "property float z"]
    if faces is not None:
        header += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    header.append("end_header")
    parts = [("\n".join(header) + "\n").encode("ascii"), vertices.tobytes()]
    if faces is not None:
        rec = np.empty(len(faces), dtype=[("n", "u1"), ("v", "<i4", (3,))])
        rec["n"] = 3
        rec["v"] = faces
        parts.append(rec.tobytes())
    return b"".join(parts)


def _read_text(path: Path) -> np.ndarray:
    text = path.read_text(encoding="utf-8", errors="replace")
    delimiter = "," if path.suffix.lower() == ".csv" or ("," in text.split("\n", 1)[0]) else None
    rows = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        parts = stripped.split(delimiter)
        try:
            values = [float(p) for p in parts[:3]]
        except ValueError:
            if not rows:  # one header line (x,y,z) is allowed
                continue
            raise FileFormatError(path, f"line {lineno} is not three numbers: {stripped[:40]!r}") from None
        if len(values) < 3:
            raise FileFormatError(path, f"line {lineno} has {len(values)} values, needs x y z")
        rows.append(values)
    return np.array(rows, dtype=float).reshape(-1, 3)


def load_point_cloud(path: str | Path, *, unit: str = "m", up: str = "z", check_25d: bool = True) -> PointCloud:
    """Load a terrain cloud file and check it; ``unit`` ('m' or 'mm') is the file's length unit
    and ``up`` the file axis pointing away from the ground."""
    path = Path(path)
    if not path.exists():
        raise FileFormatError(path, "file does not exist")
    if path.is_dir():
        raise FileFormatError(path, "is a directory, not a point cloud")
    suffix = path.suffix.lower()
    if suffix not in CLOUD_SUFFIXES:
        raise FileFormatError(path, f"unknown point cloud type {suffix or '(none)'!r}; valid: {', '.join(CLOUD_SUFFIXES)}")
    if unit not in ("m", "mm"):
        raise InputError(f"unit {unit!r} is not one of m, mm")
    if path.stat().st_size == 0:
        raise FileFormatError(path, "file is empty")
    if suffix == ".ply":
        points, _ = read_ply(path)
    elif suffix == ".npy":
        try:
            points = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise FileFormatError(path, f"not a readable .npy array: {exc}") from None
        if points.ndim != 2 or points.shape[1] < 3 or not np.issubdtype(points.dtype, np.number):
            raise FileFormatError(path, f"array has shape {points.shape} and type {points.dtype}; needs (N, 3) numbers")
        points = points[:, :3].astype(float)
    else:
        points = _read_text(path)
    return cloud_from_array(points * (1e-3 if unit == "mm" else 1.0), source=str(path), up=up, check_25d=check_25d)


def cloud_from_array(points: np.ndarray, *, source: str = "(array)", up: str = "z", check_25d: bool = True) -> PointCloud:
    """Check an (N, 3) array (metres, file axes) and turn it into a terrain cloud (z up)."""
    points = np.asarray(points, dtype=float)

    def fail(msg: str) -> None:
        if source == "(array)":
            raise InputError(f"point cloud: {msg}")
        raise FileFormatError(source, msg)

    if points.ndim != 2 or points.shape[1] != 3:
        fail(f"needs (N, 3) coordinates, got shape {points.shape}")
    if len(points) == 0:
        fail("point cloud is empty (no points)")
    bad = ~np.all(np.isfinite(points), axis=1)
    if bad.any():
        fail(f"{int(bad.sum())} points have NaN or infinite coordinates (first at row {int(np.argmax(bad))})")
    if len(points) < 3:
        fail(f"needs at least 3 points to make a surface, got {len(points)}")
    if up != "z":
        points = points @ up_transform(up).T
    if check_25d:
        problem = not_25d_reason(points)
        if problem:
            fail(f"not a 2.5D terrain over the ground plane with up = {up!r}: {problem}")
    return PointCloud(np.ascontiguousarray(points), source)


def not_25d_reason(points: np.ndarray) -> str:
    """Why a cloud (z up) is not a height field, or '' if it is one.

    Checked on a ground grid at about the mean point spacing: the cloud must spread over an area
    (not a line or a wall), and within a cell the height spread must not exceed what a slope of
    ``MAX_SLOPE_DEG`` explains, except in a small fraction of cells (rock edges, noise).
    """
    xy = points[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    extent = hi - lo
    z_range = float(np.ptp(points[:, 2]))
    if min(extent) <= 1e-9 or min(extent) < 1e-3 * max(max(extent), z_range):
        return f"the points lie on a line or a wall seen from above (ground extent {extent[0]:.4g} x {extent[1]:.4g} m)"
    n = len(points)
    cell = float(np.sqrt(extent[0] * extent[1] / n)) * 2.0
    nx = int(extent[0] / cell) + 1
    ny = int(extent[1] / cell) + 1
    ij = np.minimum(((xy - lo) / cell).astype(np.int64), [nx - 1, ny - 1])
    key = ij[:, 0] * ny + ij[:, 1]
    order = np.argsort(key, kind="stable")
    k = key[order]
    z = points[order, 2]
    starts = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
    zmax = np.maximum.reduceat(z, starts)
    zmin = np.minimum.reduceat(z, starts)
    counts = np.diff(np.r_[starts, len(k)])
    allowed = cell * np.sqrt(2.0) * np.tan(np.radians(MAX_SLOPE_DEG))
    occupied = counts >= 2
    steep = (zmax - zmin > allowed) & occupied
    frac = float(steep.sum()) / max(1, int(occupied.sum()))
    if frac > MAX_OVERHANG_FRACTION:
        return (
            f"{frac:.0%} of ground cells ({cell * 1e3:.1f} mm) hold points stacked more than {allowed * 1e3:.0f} mm apart "
            "(overhangs or a closed surface; choose another up axis)"
        )
    return ""
