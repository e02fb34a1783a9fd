"""Cell size of the uniform subdivision from the point-distribution cost model (thesis §5.2.2).

With bodies reduced to points of uniform density ``delta`` in a cube of side ``L``, cells of
side ``l`` and a boundary band of width ``w`` (the largest box edge), the work of one frame is
modelled as in-cell sorting plus updates of bodies in the boundary bands (eq. 5.2):

    F(l) = N * (1 + 6 w / l) * (3 ln l + ln delta)

``F'(l)`` has the sign of ``G(l) = l + 6w - 6w ln l - 2w ln delta``, whose minimum is at
``l = 6w``. If ``G(6w) >= 0`` the cost grows with ``l`` and the smallest useful cell is taken,
``l = 2w`` (eq. 5.3); otherwise the cost has its minimum at the larger root ``l0 >= 6w`` of
``G`` (eq. 5.4), found here by bisection. The logarithm is natural (the thesis does not say;
the sign test changes only slightly with the base).
"""

from __future__ import annotations

import math

from shared.errors import InputError


def g_of(l: float, w: float, density: float) -> float:
    """``G(l)``: positive where the modelled cost grows with the cell size."""
    return l + 6.0 * w - 6.0 * w * math.log(l) - 2.0 * w * math.log(density)


def cell_size(density: float, w: float) -> float:
    """The cost model's cell side for point density ``density`` (bodies per unit volume) and
    boundary band ``w`` (the largest box edge, i.e. a sphere's diameter)."""
    if not (w > 0 and math.isfinite(w)):
        raise InputError(f"band width w must be positive and finite, got {w}")
    if not (density > 0 and math.isfinite(density)):
        return 2.0 * w  # no bodies: any cell will do; the smallest keeps cells cheap
    if g_of(6.0 * w, w, density) >= 0.0:
        return 2.0 * w  # eq. (5.3)
    lo, hi = 6.0 * w, 12.0 * w
    while g_of(hi, w, density) < 0.0:  # G grows without bound beyond 6w
        hi *= 2.0
    for _ in range(100):  # eq. (5.4): bisection on the larger root
        mid = 0.5 * (lo + hi)
        if g_of(mid, w, density) < 0.0:
            lo = mid
        else:
            hi = mid
    return hi
