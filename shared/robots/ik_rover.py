"""Closed-form inverse kinematics of the seed-004 lunar-rover arm (position of point C only).

The arm is a standard-DH chain whose joint 2 and joint 3 axes are parallel (Table 1: alpha_2 = 0).
Seed 004 solves it in three steps, and so does this module:

1. Joint 2 and joint 3 move point C only inside the plane normal to their common axis, so C's
   distance from that plane is a constant of the arm. Written in frame 1 this gives one equation
   ``A sin(theta_1) + B cos(theta_1) = C`` (seed 004's theta_1, which the paper writes with the
   tangent half-angle ``2 arctan((x_c +- sqrt(...)) / ...)``): two roots.
2. In that plane the distance from the joint-2 axis to C fixes theta_3 (the paper's
   ``2 arctan((-D +- sqrt(C^2 + D^2 - E^2)) / (E - C))``): two roots per theta_1.
3. theta_2 then follows from one ``atan2`` (the paper's arctan of ``A11, A12`` terms).

The half-angle forms divide by zero at theta = 180 deg; the ``atan2 +- acos`` form used here
solves the same equations without that gap. Up to four solutions; ``shared.robots.ik`` maps them
into the joint ranges, removes duplicates and orders them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from shared.errors import KinematicsError
from shared.robots.description import DHJoint

#: a cosine this far beyond +-1 from rounding still counts as touching the workspace boundary
BOUNDARY_TOLERANCE = 1e-9


def _sin_cos_roots(a: float, b: float, c: float) -> list[float]:
    """Roots theta of ``a sin(theta) + b cos(theta) = c`` (0, 1 or 2 of them)."""
    r = float(np.hypot(a, b))
    if r < 1e-12:
        return [0.0] if abs(c) < 1e-12 else []  # every theta works: take 0
    ratio = c / r
    if abs(ratio) > 1.0 + BOUNDARY_TOLERANCE:
        return []
    phi = float(np.arctan2(a, b))  # a sin + b cos = r cos(theta - phi)
    spread = float(np.arccos(np.clip(ratio, -1.0, 1.0)))
    return [phi + spread, phi - spread] if spread > 1e-12 else [phi]


def _dh(theta: float, joint: DHJoint) -> np.ndarray:
    """Standard DH transform Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(joint.alpha), np.sin(joint.alpha)
    return np.array([
        [ct, -st * ca, st * sa, joint.a * ct],
        [st, ct * ca, -ct * sa, joint.a * st],
        [0.0, sa, ca, joint.d],
        [0.0, 0.0, 0.0, 1.0],
    ])


def rover_ik_all(joints: Sequence[DHJoint], flange_T_tool: np.ndarray, base_p_tool: np.ndarray) -> list[np.ndarray]:
    """All joint vectors (radians, the robot's own joint variables) putting the tool point at
    ``base_p_tool`` (3,); ``[]`` if the point is out of reach.

    ``joints`` must be a standard-DH 3R chain with parallel joint-2 and joint-3 axes, as the rover
    of seed 004 is; ``flange_T_tool`` places point C in the last DH frame.
    """
    if len(joints) != 3:
        raise KinematicsError(f"the rover solver needs 3 joints, the robot has {len(joints)}")
    j1, j2, j3 = joints
    if abs(np.sin(j2.alpha)) > 1e-9:
        raise KinematicsError("the rover solver needs parallel joint-2 and joint-3 axes (alpha_2 = 0 or 180 deg)")
    p = np.asarray(base_p_tool, dtype=float).reshape(3)
    # point C in frame 3 before joint 3 turns: frame3_p_tool = Rz(theta_3) @ w
    w = (_dh(0.0, j3) @ np.append(np.asarray(flange_T_tool, dtype=float)[:3, 3], 1.0))[:3]
    ca2, sa2 = np.cos(j2.alpha), np.sin(j2.alpha)  # alpha_2 is 0 or pi: a reflection of z
    ca1, sa1 = np.cos(j1.alpha), np.sin(j1.alpha)
    # frame1_p = Rz(theta_2) @ (Rz(theta_3) w + (a2, 0, d2)) up to alpha_2's reflection:
    # its z component is the constant ``plane`` below
    plane = j2.d + ca2 * w[2]
    out: list[np.ndarray] = []
    # frame 1 coordinates of p: Rx(-alpha_1) (Rz(-theta_1) p - (a1, 0, d1))
    # z-component: -sa1 * (-px s1 + py c1) + ca1 * (pz - d1) = plane
    for theta1 in _sin_cos_roots(sa1 * p[0], -sa1 * p[1], plane - ca1 * (p[2] - j1.d)):
        c1, s1 = np.cos(theta1), np.sin(theta1)
        hx = p[0] * c1 + p[1] * s1 - j1.a
        hy = -p[0] * s1 + p[1] * c1
        hz = p[2] - j1.d
        gx, gy = hx, ca1 * hy + sa1 * hz  # C in frame 1, inside the joint-2 plane
        # |g|^2 = |w_xy|^2 + a2^2 + 2 a2 (w_x cos theta_3 - w_y sin theta_3)   (a2 != 0)
        if abs(j2.a) < 1e-12:
            raise KinematicsError("the rover solver needs a non-zero a_2 (upper-arm length)")
        k = (gx * gx + gy * gy - w[0] ** 2 - w[1] ** 2 - j2.a ** 2) / (2.0 * j2.a)
        for theta3 in _sin_cos_roots(-w[1], w[0], k):
            c3, s3 = np.cos(theta3), np.sin(theta3)
            vx = c3 * w[0] - s3 * w[1] + j2.a
            vy = ca2 * (s3 * w[0] + c3 * w[1])
            theta2 = float(np.arctan2(gy, gx) - np.arctan2(vy, vx))
            theta = np.array([theta1, theta2, theta3])
            offsets = np.array([j.offset for j in joints])
            signs = np.array([j.sign for j in joints], dtype=float)
            out.append((theta - offsets) * signs)
    return out
