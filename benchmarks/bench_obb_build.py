"""OBB tree build: the robot's and the cell's meshes, as every console and telerobot builds them at start.

The hierarchy of seed 002 (``shared.collision.obb_tree``) built by its numba build
(``shared.collision.obb_build``), by the Python reference of the same algorithm, and by coal's
``BVHModelOBBRSS`` (an OBB+RSS tree, coal's default for meshes) on the same triangles: the
default cell's link and object meshes. Best of ``--repeat`` wall times. Run:
``teleprog bench obb_build [--json]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _meshes() -> list[tuple[np.ndarray, np.ndarray]]:
    """The (vertices, faces) the default cell's scene builds trees of."""
    import shared.collision.scene as scene
    from shared.cells.loader import DEFAULT_CELL, load_cell

    grabbed: list[tuple[np.ndarray, np.ndarray]] = []
    build = scene.build_obb_tree

    def grab(vertices, faces, leaf_size=1, **kw):
        grabbed.append((np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64)))
        return build(vertices, faces, leaf_size, **kw)

    scene.build_obb_tree = grab
    try:
        scene.SceneModel.from_cell(load_cell(DEFAULT_CELL))
    finally:
        scene.build_obb_tree = build
    return grabbed


def _best(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--json", action="store_true")


def main_with(args: argparse.Namespace) -> int:
    import coal

    from shared.collision.obb_tree import build_obb_tree

    meshes = _meshes()
    build_obb_tree(*meshes[0])  # the compiled build loads (or compiles once) here, not in the timing

    def coal_build() -> None:
        for v, f in meshes:
            model = coal.BVHModelOBBRSS()
            model.beginModel(len(f), len(v))
            model.addVertices(v)
            model.addTriangles(f)
            model.endModel()

    out = {
        "bodies": len(meshes), "triangles": int(sum(len(f) for _, f in meshes)),
        "compiled_s": _best(lambda: [build_obb_tree(v, f) for v, f in meshes], args.repeat),
        "python_reference_s": _best(lambda: [build_obb_tree(v, f, compiled=False) for v, f in meshes], max(1, args.repeat // 2)),
        "coal_obbrss_s": _best(coal_build, args.repeat),
    }
    out["ratio_python"] = out["python_reference_s"] / out["compiled_s"]
    out["ratio_coal"] = out["coal_obbrss_s"] / out["compiled_s"]
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"OBB trees of the default cell's {out['bodies']} meshes ({out['triangles']} triangles):")
        print(f"  ours (numba) {1e3 * out['compiled_s']:.1f} ms; Python reference {1e3 * out['python_reference_s']:.0f} ms "
              f"({out['ratio_python']:.0f}x); coal BVHModelOBBRSS {1e3 * out['coal_obbrss_s']:.1f} ms (coal/ours {out['ratio_coal']:.2f})")
    return 0


def main(argv=None, prog: str | None = None) -> int:
    p = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    add_arguments(p)
    return main_with(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
