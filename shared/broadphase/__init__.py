"""Many-body collision detection (thesis chapter 5): which of N spheres overlap, frame by frame.

Methods (one module each, one interface: ``Detector.update(centres, radii) -> (K, 2) pairs``):
``usscd`` uniform subdivision (§5.2), ``usscd_skin`` the same run only when a skin list expires
(engineered for speed), ``scd`` sort-and-sweep, ``icollide`` incremental
sweep-and-prune, ``pbnuss`` projection-histogram subdivision (§5.3.2), ``cbass`` clustering-based
subdivision over HDBC (§5.3.3-5.3.4), ``ugrid`` and ``ugrid_skin`` engineered for speed (one
entry a body in diameter-wide columns, branch-free neighbour filter; see ``ugrid.py``), ``brute``
the reference. ``workloads`` makes the
particle-sedimentation scenes.
"""

from __future__ import annotations

from collections.abc import Callable

from shared.broadphase.base import Detector
from shared.errors import UnknownNameError


def _registry() -> dict[str, Callable[[], Detector]]:
    from shared.broadphase.brute import BruteForce
    from shared.broadphase.cbass import CBASS
    from shared.broadphase.icollide import ICollide
    from shared.broadphase.pbnuss import PBNUSS
    from shared.broadphase.scd import SCD
    from shared.broadphase.ugrid import SkinUGrid, UGrid
    from shared.broadphase.usscd import USSCD
    from shared.broadphase.verlet import SkinUSSCD

    return {"usscd": USSCD, "usscd_skin": SkinUSSCD, "scd": SCD, "icollide": ICollide, "pbnuss": PBNUSS, "cbass": CBASS,
            "ugrid": UGrid, "ugrid_skin": SkinUGrid, "brute": BruteForce}


METHODS = ("usscd", "usscd_skin", "scd", "icollide", "pbnuss", "cbass", "ugrid", "ugrid_skin", "brute")


def make_detector(name: str, **options) -> Detector:
    """A fresh detector by method name (see METHODS)."""
    reg = _registry()
    if name not in reg:
        raise UnknownNameError("broadphase method", name, METHODS)
    return reg[name](**options)


def warm_up() -> None:
    """Compile every numba kernel of the broad phase once, serial and parallel compilations alike
    (all ``cache=True``: numba keeps them in ``__pycache__`` beside the sources, and every later
    process loads them instead of compiling). ``scripts/setup`` calls it, so no test or console
    compiles, and two processes never compile the same kernel at once.

    Every method runs a few frames of a moving scene (skin lists built, kept and rebuilt) and of a
    crowded one (columns kept sorted by z, z windows), first with the parallel thresholds lowered
    to a few bodies, so the parallel kernels compile on a small scene, then at the defaults, where
    the same scenes take the serial compilations."""
    from shared.broadphase import base, columns, grid, verlet
    from shared.broadphase.columns import ColumnEngine
    from shared.broadphase.workloads import make_scene

    thresholds = {(grid, "PARALLEL_MIN"): 1, (columns, "PARALLEL_MIN"): 1, (base, "STATS_PARALLEL_MIN"): 1,
                  (verlet, "LIST_PARALLEL_MIN"): 1}
    saved = {key: getattr(*key) for key in thresholds}
    try:
        for lowered in (True, False):
            for (module, name), value in thresholds.items():
                setattr(module, name, value if lowered else saved[(module, name)])
            for method in METHODS:
                for kind in ("uniform", "gaussian"):
                    scene = make_scene(kind, n=400, size=40.0, speed=0.3, radius_spread=0.4, seed=1, clusters=2)
                    detector = make_detector(method)
                    if method == "ugrid":  # every column sorted and windowed, on a scene this small
                        detector._engine = ColumnEngine(sort_min=0, zwin_min=0)
                    for _ in range(4):
                        detector.update(scene.centres, scene.radii)
                        scene.step()
    finally:
        for (module, name), value in saved.items():
            setattr(module, name, value)


__all__ = ["METHODS", "Detector", "make_detector", "warm_up"]
