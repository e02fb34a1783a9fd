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


__all__ = ["METHODS", "Detector", "make_detector"]
