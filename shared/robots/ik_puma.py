"""Closed-form inverse kinematics of the PUMA 562 of thesis Table 4.1 (modified / Craig DH).

The chain (``prev_T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)``) must have the PUMA
structure::

    i   alpha_{i-1}   a_{i-1}   d_i
    1     0            0        d1    (any; usually 0)
    2   -90            0        d2    (shoulder offset)
    3     0            a2 != 0  d3    (any; adds to the shoulder offset since z3 is parallel to z2)
    4    90            a3       d4    (a3, d4 not both 0)
    5   -90            0        0
    6    90            0        d6    (any; flange offset along z6)

so that frames 4, 5 and 6 meet at the wrist centre (a spherical wrist) when ``d6 = 0``.
Each joint's DH angle is ``theta = sign * q + offset``.

Derivation (theta_i abbreviated c_i, s_i; h = d2 + d3; phi = atan2(d4, a3)):

* Wrist centre ``w = p - d6 z6`` and, in frame 0,
  ``(w_x, w_y) = Rz(theta1) (r, h)`` and ``d1 - w_z = s2 X + c2 Y`` with ``r = c2 X - s2 Y``,
  ``X = a2 + a3 c3 + d4 s3``, ``Y = a3 s3 - d4 c3``.
* theta1: ``r = +-sqrt(w_x^2 + w_y^2 - h^2)``, ``theta1 = atan2(w_y, w_x) - atan2(h, r)``.
* theta3: ``X^2 + Y^2 = r^2 + z'^2`` gives ``a3 c3 + d4 s3 = K``, so
  ``theta3 = phi +- acos(K / sqrt(a3^2 + d4^2))``.
* theta2: ``(r, z') = R2d(theta2) (X, Y)`` so ``theta2 = atan2(z', r) - atan2(Y, X)``.
* Wrist: ``3_R_6 = Ry(-theta4) Rz(theta5) Ry(-theta6) Rx(90)``; its third column is
  ``(c4 s5, -c5, s4 s5)`` which gives theta4 (two choices, pi apart); then theta5 and theta6
  come from ``4_R_6 = Ry(theta5) Rz(theta6)`` with that theta4, which stays exact near the wrist
  singularity (the error in theta4 there is absorbed by theta6).

Singular cases: at the wrist singularity (``sin theta5 = 0``) only ``theta4 + theta6`` (or the
difference, at ``theta5 = pi``) is fixed; the solver returns one representative per arm
configuration with ``q4 = q4_singular`` (0 unless the caller passes e.g. the current q4). At the
shoulder singularity (``h = 0`` and the wrist centre on the joint-1 axis) ``q1`` is free and set
to 0. When the elbow is fully stretched or the wrist centre lies on the cylinder of radius
``|h|`` around joint 1, the two coinciding solutions are returned once.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from shared.errors import InputError
from shared.robots.description import DHJoint

#: the alpha_{i-1} pattern of the PUMA (radians)
PUMA_ALPHAS = (0.0, -math.pi / 2, 0.0, math.pi / 2, -math.pi / 2, math.pi / 2)
#: tolerance on the structural parameters (rad for alpha, m for lengths)
STRUCTURE_TOLERANCE = 1e-9
#: a target this far (relative) beyond a reach boundary is treated as on it
REACH_TOLERANCE = 1e-10
#: below this (m) the wrist centre is on the joint-1 axis (shoulder singularity, h = 0)
SHOULDER_SINGULAR = 1e-12
#: below this |sin theta5| the wrist is singular and q4 is set to the representative (rounding
#: in the arm solution alone reaches ~1e-10 near q5 = pi; the orientation error of fixing q4 here is
#: below 1e-9 rad)
WRIST_SINGULAR = 1e-9

_TWO_PI = 2.0 * math.pi


def _wrap(angle: float) -> float:
    """Angle into (-pi, pi]."""
    out = math.pi - (math.pi - angle) % _TWO_PI
    return out + _TWO_PI if out <= -math.pi else out  # the modulo can round up to 2 pi


def check_puma_structure(joints: Sequence[DHJoint]) -> None:
    """Raise ``InputError`` unless ``joints`` is a PUMA-type modified-DH chain (see module doc)."""
    if len(joints) != 6:
        raise InputError(f"the PUMA closed-form IK needs 6 joints, the table has {len(joints)}")
    alphas = [j.alpha for j in joints]
    if any(abs(math.remainder(a - b, _TWO_PI)) > STRUCTURE_TOLERANCE for a, b in zip(alphas, PUMA_ALPHAS)):
        got = ", ".join(f"{math.degrees(a):g}" for a in alphas)
        raise InputError(
            f"the PUMA closed-form IK needs alpha_(i-1) = 0, -90, 0, 90, -90, 90 deg (modified DH); "
            f"the table has {got}"
        )
    for index, attr in ((0, "a"), (1, "a"), (4, "a"), (5, "a"), (4, "d")):
        value = getattr(joints[index], attr)
        if abs(value) > STRUCTURE_TOLERANCE:
            raise InputError(
                f"the PUMA closed-form IK needs {attr} of joint {index + 1} = 0 "
                f"(a0 = a1 = a4 = a5 = 0 and d5 = 0 for a spherical wrist); it is {value:g} m"
            )
    if abs(joints[2].a) <= STRUCTURE_TOLERANCE:
        raise InputError("the PUMA closed-form IK needs a non-zero upper-arm length a2 (joint 3's a)")
    if math.hypot(joints[3].a, joints[3].d) <= STRUCTURE_TOLERANCE:
        raise InputError("the PUMA closed-form IK needs a non-zero forearm (joint 4's a and d both 0)")
    for i, j in enumerate(joints, start=1):
        if j.sign not in (1, -1):
            raise InputError(f"joint {i} sign must be 1 or -1, got {j.sign}")


def _arm_solutions(
    wx: float, wy: float, wz: float, d1: float, h: float, a2: float, a3: float, d4: float, q1_free: float
) -> list[tuple[float, float, float]]:
    """(theta1, theta2, theta3) placing the wrist centre at ``w`` (up to 4)."""
    rho2 = wx * wx + wy * wy
    disc = rho2 - h * h
    if math.sqrt(rho2) < SHOULDER_SINGULAR and abs(h) < SHOULDER_SINGULAR:
        shoulders = [(q1_free, 0.0)]  # theta1 free: representative, wrist centre on the axis
    else:
        if disc < 0.0:
            if disc < -REACH_TOLERANCE * max(rho2, h * h, 1e-300):
                return []  # inside the cylinder of radius |h| around joint 1
            disc = 0.0
        root = math.sqrt(disc)
        base = math.atan2(wy, wx)
        radii = (root, -root) if root > 0.0 else (0.0,)
        shoulders = [(base - math.atan2(h, r), r) for r in radii]

    zp = d1 - wz
    rho3 = math.hypot(a3, d4)
    phi = math.atan2(d4, a3)
    out: list[tuple[float, float, float]] = []
    for theta1, r in shoulders:
        k = (r * r + zp * zp - a2 * a2 - a3 * a3 - d4 * d4) / (2.0 * a2)
        x = k / rho3
        if abs(x) > 1.0 + REACH_TOLERANCE:
            continue  # too far (stretched) or too close (folded)
        if abs(x) >= 1.0:
            elbows = [phi if x > 0 else phi + math.pi]
        else:
            spread = math.acos(x)
            elbows = [phi + spread, phi - spread]
        for theta3 in elbows:
            c3, s3 = math.cos(theta3), math.sin(theta3)
            big_x = a2 + a3 * c3 + d4 * s3
            big_y = a3 * s3 - d4 * c3
            theta2 = math.atan2(zp, r) - math.atan2(big_y, big_x)
            out.append((theta1, theta2, theta3))
    return out


def puma_ik_all(
    joints: Sequence[DHJoint], base_T_flange: np.ndarray, *, q4_singular: float = 0.0
) -> list[np.ndarray]:
    """All joint solutions ``q`` (6,) radians, wrapped into (-pi, pi], placing the flange (DH
    frame 6) at ``base_T_flange`` (4, 4, metres, base frame). Up to 8; ``[]`` if unreachable.

    ``q4_singular`` is the q4 (rad) used at the wrist singularity, where only q4 +- q6 is fixed.
    Raises ``InputError`` if the table does not have the PUMA structure or the pose is not a
    finite (4, 4) array.
    """
    check_puma_structure(joints)
    target = np.asarray(base_T_flange, dtype=float)
    if target.shape != (4, 4) or not np.all(np.isfinite(target)):
        raise InputError(f"the PUMA IK needs a finite (4, 4) flange pose, got shape {target.shape}")
    (r00, r01, r02, px), (r10, r11, r12, py), (r20, r21, r22, pz), _ = target.tolist()

    j1, j2, j3, j4, j5, j6 = joints
    d1, h, a2, a3, d4, d6 = j1.d, j2.d + j3.d, j3.a, j4.a, j4.d, j6.d
    # wrist centre: the flange origin moved back along z6
    wx, wy, wz = px - d6 * r02, py - d6 * r12, pz - d6 * r22

    theta1_free = j1.offset  # q1 = 0 at the shoulder singularity
    theta4_free = j4.sign * q4_singular + j4.offset
    c4f, s4f = math.cos(theta4_free), math.sin(theta4_free)

    solutions: list[np.ndarray] = []
    cached_theta1: float | None = None
    a_rows: tuple[tuple[float, float, float], ...] = ()
    for theta1, theta2, theta3 in _arm_solutions(wx, wy, wz, d1, h, a2, a3, d4, theta1_free):
        if theta1 != cached_theta1:
            # A = Rx(90) Rz(-theta1) R: rows (row0 of Rz^T R, -row2 of R, row1 of Rz^T R)
            c1, s1 = math.cos(theta1), math.sin(theta1)
            b0 = (c1 * r00 + s1 * r10, c1 * r01 + s1 * r11, c1 * r02 + s1 * r12)
            b1 = (-s1 * r00 + c1 * r10, -s1 * r01 + c1 * r11, -s1 * r02 + c1 * r12)
            a_rows = (b0, (-r20, -r21, -r22), b1)
            cached_theta1 = theta1
        # rows m0, m1, m2 of 3_R_6 = Rz(-theta23) A  (3_R_0 = Rz(-theta23) Rx(90) Rz(-theta1))
        theta23 = theta2 + theta3
        c23, s23 = math.cos(theta23), math.sin(theta23)
        row0, row1, m2 = a_rows
        m0 = [c23 * row0[k] + s23 * row1[k] for k in range(3)]
        m1 = [-s23 * row0[k] + c23 * row1[k] for k in range(3)]
        # third column (c4 s5, -c5, s4 s5)
        s5_abs = math.hypot(m0[2], m2[2])
        if s5_abs < WRIST_SINGULAR:
            wrists = [(c4f, s4f, theta4_free)]
        else:
            theta4 = math.atan2(m2[2], m0[2])
            c4, s4 = m0[2] / s5_abs, m2[2] / s5_abs
            wrists = [(c4, s4, theta4), (-c4, -s4, theta4 + math.pi)]
        for c4, s4, theta4 in wrists:
            # 4_R_6 = Rz(-theta4) Rx(-90) 3_R_6 = Ry(theta5) Rz(theta6)
            theta5 = math.atan2(c4 * m0[2] + s4 * m2[2], -m1[2])
            theta6 = math.atan2(-s4 * m0[0] + c4 * m2[0], -s4 * m0[1] + c4 * m2[1])
            thetas = (theta1, theta2, theta3, theta4, theta5, theta6)
            solutions.append(
                np.array([_wrap(j.sign * (t - j.offset)) for j, t in zip(joints, thetas)])
            )
    return solutions
