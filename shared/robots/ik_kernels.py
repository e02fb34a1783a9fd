"""Nearest-solution inverse kinematics for jogging and path following: one compiled call.

``solve_ik`` (``shared.robots.ik``) returns every solution, mapped into the joint ranges,
deduplicated and sorted nearest first; most callers (jogging, the planner's next step, the
program checks) then read only the first. ``solve_ik_nearest`` returns that first solution (or
None where ``solve_ik`` returns none) without building the list: for the PUMA closed form the
whole of it (tool and base frames, the up-to-8 analytic solutions, the range mapping with its
2 pi variants and limit clamp, the duplicate rule and the nearest pick) runs in one numba kernel
that follows ``puma_ik_all`` and ``solve_ik`` step for step, so the answer is the same solution
to rounding. Robots without that closed form (the rover, DLS robots) go through ``solve_ik``.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np
from numba import njit

from shared.errors import InputError
from shared.robots.ik import DUPLICATE_TOLERANCE, solve_ik
from shared.robots.ik_puma import REACH_TOLERANCE, SHOULDER_SINGULAR, WRIST_SINGULAR, check_puma_structure
from shared.robots.model import LIMIT_TOLERANCE, Robot
from shared.spatial import invert

JIT = dict(cache=True, nogil=True, fastmath=False)

_TWO_PI = 2.0 * math.pi
_F64 = np.dtype(np.float64)


@dataclass(frozen=True)
class PumaKernelParams:
    """What the kernel needs of a PUMA robot file, extracted once per description."""

    packed: np.ndarray  # (50,) lengths d1, h = d2 + d3, a2, a3, d4, d6 (m); joint signs (+1 / -1);
    # DH angle offsets (rad); chain_T_base (4 x 4, the inverse of base_T_chain); tool_T_flange
    # (4 x 4, the inverse of flange_T_tool): one array, so the kernel call types one argument
    tolerance: float  # the robot file's ik_limit_tolerance, at least LIMIT_TOLERANCE (rad)


#: id(description) -> (weak reference to it, its parameters); the entry goes with the description
_PARAMS: dict[int, tuple[weakref.ref, PumaKernelParams]] = {}


def _puma_params(robot: Robot) -> PumaKernelParams:
    """The kernel parameters of ``robot``'s description (checked and cached on first use)."""
    desc = robot.description
    hit = _PARAMS.get(id(desc))
    if hit is not None and hit[0]() is desc:
        return hit[1]
    check_puma_structure(desc.joints)
    j1, j2, j3, j4, _j5, j6 = desc.joints
    params = PumaKernelParams(
        packed=np.concatenate([
            [j1.d, j2.d + j3.d, j3.a, j4.a, j4.d, j6.d],
            [float(j.sign) for j in desc.joints],
            [float(j.offset) for j in desc.joints],
            np.asarray(invert(desc.base_T_chain), dtype=float).ravel(),
            np.asarray(invert(desc.flange_T_tool), dtype=float).ravel(),
        ]).astype(float),
        tolerance=max(float(desc.ik_limit_tolerance), LIMIT_TOLERANCE),
    )
    key = id(desc)
    _PARAMS[key] = (weakref.ref(desc, lambda _ref: _PARAMS.pop(key, None)), params)
    return params


@njit(**JIT)
def _wrap_py(angle: float) -> float:
    """``ik_puma._wrap``: angle into (-pi, pi], bit for bit. The modulo (a slow ``fmod``) is skipped
    where it returns its argument unchanged (``0 <= x < 2 pi``), the usual case."""
    x = math.pi - angle
    out = math.pi - (x if 0.0 <= x < _TWO_PI else x % _TWO_PI)
    return out + _TWO_PI if out <= -math.pi else out


@njit(**JIT)
def _wrap_np(angle: float) -> float:
    """``ik._wrap`` on one value (the same fold, as numpy computes it), bit for bit."""
    x = np.pi - angle
    out = np.pi - (x if 0.0 <= x < 2.0 * np.pi else np.mod(x, 2.0 * np.pi))
    return out + 2.0 * np.pi if out <= -np.pi else out


@njit(**JIT)
def _matmul4(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            s = 0.0
            for k in range(4):
                s += a[i, k] * b[k, j]
            out[i, j] = s
    return out


@njit(**JIT)
def _puma_raw(
    target: np.ndarray, lengths: np.ndarray, signs: np.ndarray, offsets: np.ndarray, q4_singular: float
) -> tuple[np.ndarray, int]:
    """``puma_ik_all``: the raw solutions (rows of an (8, 6) array, the first ``n`` filled), in
    the same order, wrapped into (-pi, pi]."""
    raw = np.empty((8, 6))
    n = 0
    r00, r01, r02, px = target[0, 0], target[0, 1], target[0, 2], target[0, 3]
    r10, r11, r12, py = target[1, 0], target[1, 1], target[1, 2], target[1, 3]
    r20, r21, r22, pz = target[2, 0], target[2, 1], target[2, 2], target[2, 3]
    d1, h, a2, a3, d4, d6 = lengths[0], lengths[1], lengths[2], lengths[3], lengths[4], lengths[5]
    wx, wy, wz = px - d6 * r02, py - d6 * r12, pz - d6 * r22
    theta1_free = offsets[0]
    theta4_free = signs[3] * q4_singular + offsets[3]
    c4f, s4f = math.cos(theta4_free), math.sin(theta4_free)

    # shoulders (theta1, r): up to 2
    sh_t0 = sh_r0 = sh_t1 = sh_r1 = 0.0
    rho2 = wx * wx + wy * wy
    disc = rho2 - h * h
    if math.sqrt(rho2) < SHOULDER_SINGULAR and abs(h) < SHOULDER_SINGULAR:
        sh_t0 = theta1_free
        n_sh = 1
    else:
        if disc < 0.0:
            if disc < -REACH_TOLERANCE * max(rho2, h * h, 1e-300):
                return raw, 0
            disc = 0.0
        root = math.sqrt(disc)
        base = math.atan2(wy, wx)
        if root > 0.0:
            sh_t0, sh_r0 = base - math.atan2(h, root), root
            sh_t1, sh_r1 = base - math.atan2(h, -root), -root
            n_sh = 2
        else:
            sh_t0 = base - math.atan2(h, 0.0)
            n_sh = 1

    zp = d1 - wz
    rho3 = math.hypot(a3, d4)
    phi = math.atan2(d4, a3)
    for i_sh in range(n_sh):
        theta1 = sh_t0 if i_sh == 0 else sh_t1
        r = sh_r0 if i_sh == 0 else sh_r1
        k = (r * r + zp * zp - a2 * a2 - a3 * a3 - d4 * d4) / (2.0 * a2)
        x = k / rho3
        if abs(x) > 1.0 + REACH_TOLERANCE:
            continue
        if abs(x) >= 1.0:
            el0 = phi if x > 0 else phi + math.pi
            el1 = el0
            n_el = 1
        else:
            spread = math.acos(x)
            el0 = phi + spread
            el1 = phi - spread
            n_el = 2
        # A = Rx(90) Rz(-theta1) R: rows (row0 of Rz^T R, -row2 of R, row1 of Rz^T R)
        c1, s1 = math.cos(theta1), math.sin(theta1)
        a00, a01, a02 = c1 * r00 + s1 * r10, c1 * r01 + s1 * r11, c1 * r02 + s1 * r12
        a10, a11, a12 = -r20, -r21, -r22
        m20, m21, m22 = -s1 * r00 + c1 * r10, -s1 * r01 + c1 * r11, -s1 * r02 + c1 * r12
        for i_el in range(n_el):
            theta3 = el0 if i_el == 0 else el1
            c3, s3 = math.cos(theta3), math.sin(theta3)
            big_x = a2 + a3 * c3 + d4 * s3
            big_y = a3 * s3 - d4 * c3
            theta2 = math.atan2(zp, r) - math.atan2(big_y, big_x)
            # rows m0, m1 of 3_R_6 = Rz(-theta23) A
            theta23 = theta2 + theta3
            c23, s23 = math.cos(theta23), math.sin(theta23)
            m00 = c23 * a00 + s23 * a10
            m01 = c23 * a01 + s23 * a11
            m02 = c23 * a02 + s23 * a12
            m12 = -s23 * a02 + c23 * a12
            s5_abs = math.hypot(m02, m22)
            if s5_abs < WRIST_SINGULAR:
                n_wr = 1
                wc0, ws0, wt0 = c4f, s4f, theta4_free
                wc1, ws1, wt1 = 0.0, 0.0, 0.0
            else:
                n_wr = 2
                wt0 = math.atan2(m22, m02)
                wc0, ws0 = m02 / s5_abs, m22 / s5_abs
                wc1, ws1, wt1 = -wc0, -ws0, wt0 + math.pi
            for i_wr in range(n_wr):
                if i_wr == 0:
                    c4, s4, theta4 = wc0, ws0, wt0
                else:
                    c4, s4, theta4 = wc1, ws1, wt1
                theta5 = math.atan2(c4 * m02 + s4 * m22, -m12)
                theta6 = math.atan2(-s4 * m00 + c4 * m20, -s4 * m01 + c4 * m21)
                raw[n, 0] = _wrap_py(signs[0] * (theta1 - offsets[0]))
                raw[n, 1] = _wrap_py(signs[1] * (theta2 - offsets[1]))
                raw[n, 2] = _wrap_py(signs[2] * (theta3 - offsets[2]))
                raw[n, 3] = _wrap_py(signs[3] * (theta4 - offsets[3]))
                raw[n, 4] = _wrap_py(signs[4] * (theta5 - offsets[4]))
                raw[n, 5] = _wrap_py(signs[5] * (theta6 - offsets[5]))
                n += 1
    return raw, n


@njit(**JIT)
def _nearest_of(
    raw: np.ndarray, n_raw: int, q_ref: np.ndarray, lower: np.ndarray, upper: np.ndarray,
    tolerance: float, respect_limits: bool, out: np.ndarray,
) -> bool:
    """``solve_ik``'s candidate list (range variants in ``itertools.product`` order, or the
    wrapped rows), its duplicate rule (a candidate within ``DUPLICATE_TOLERANCE`` of any earlier
    one is dropped) and its first entry after the stable sort by squared distance to ``q_ref``,
    written to ``out``. False where the list is empty."""
    dof = raw.shape[1]
    wrapped = np.empty((n_raw, dof))
    for r in range(n_raw):
        for i in range(dof):
            wrapped[r, i] = _wrap_np(raw[r, i])
    if respect_limits:
        k_lo = np.empty((n_raw, dof), dtype=np.int64)
        k_hi = np.empty((n_raw, dof), dtype=np.int64)
        total = 0
        for r in range(n_raw):
            count = 1
            for i in range(dof):
                k_lo[r, i] = int(np.ceil((lower[i] - tolerance - wrapped[r, i]) / _TWO_PI))
                k_hi[r, i] = int(np.floor((upper[i] + tolerance - wrapped[r, i]) / _TWO_PI))
                span = k_hi[r, i] - k_lo[r, i] + 1
                count = count * span if span > 0 else 0
            total += count
        cand = np.empty((total, dof))
        n = 0
        digit = np.empty(dof, dtype=np.int64)
        for r in range(n_raw):
            feasible = True
            for i in range(dof):
                if k_hi[r, i] < k_lo[r, i]:
                    feasible = False
            if not feasible:
                continue
            for i in range(dof):
                digit[i] = k_lo[r, i]
            while True:
                for i in range(dof):
                    v = wrapped[r, i] + _TWO_PI * digit[i]
                    cand[n, i] = min(max(v, lower[i]), upper[i])
                n += 1
                # odometer: the last joint turns fastest (itertools.product order)
                i = dof - 1
                while i >= 0:
                    if digit[i] < k_hi[r, i]:
                        digit[i] += 1
                        break
                    digit[i] = k_lo[r, i]
                    i -= 1
                if i < 0:
                    break
    else:
        cand = wrapped
        n = n_raw
    best = -1
    best_d = np.inf
    for j in range(n):
        dropped = False
        for i in range(j):
            m = 0.0
            for c in range(dof):
                m = max(m, abs(cand[j, c] - cand[i, c]))
            if m <= DUPLICATE_TOLERANCE:
                dropped = True
                break
        if dropped:
            continue
        d = 0.0
        for c in range(dof):
            e = cand[j, c] - q_ref[c]
            d += e * e
        if d < best_d:
            best_d = d
            best = j
    if best < 0:
        return False
    for c in range(dof):
        out[c] = cand[best, c]
    return True


@njit(**JIT)
def puma_nearest_packed(
    base_T_tool: np.ndarray, packed: np.ndarray, q_ref: np.ndarray, lower: np.ndarray, upper: np.ndarray,
    tolerance: float, respect_limits: bool, out: np.ndarray,
) -> int:
    """``puma_nearest_kernel`` with the robot's parameters in one array (``PumaKernelParams.packed``):
    fewer arguments for the dispatcher to type on every call. Also -3: the pose is not (4, 4);
    -4: ``q_ref`` is not (6,)."""
    if base_T_tool.shape[0] != 4 or base_T_tool.shape[1] != 4:
        return -3
    if q_ref.shape[0] != 6 or out.shape[0] != 6:
        return -4
    return puma_nearest_kernel(
        base_T_tool, packed[18:34].reshape(4, 4), packed[34:50].reshape(4, 4),
        packed[0:6], packed[6:12], packed[12:18], q_ref, lower, upper, tolerance, respect_limits, out,
    )


@njit(**JIT)
def puma_nearest_kernel(
    base_T_tool: np.ndarray, chain_T_base: np.ndarray, tool_T_flange: np.ndarray,
    lengths: np.ndarray, signs: np.ndarray, offsets: np.ndarray,
    q_ref: np.ndarray, lower: np.ndarray, upper: np.ndarray, tolerance: float, respect_limits: bool,
    out: np.ndarray,
) -> int:
    """The PUMA solution nearest ``q_ref`` into ``out``: 1 found, 0 none, -1 a non-finite pose,
    -2 a non-finite ``q_ref``."""
    for i in range(q_ref.shape[0]):
        if not np.isfinite(q_ref[i]):
            return -2
    for i in range(4):
        for j in range(4):
            if not np.isfinite(base_T_tool[i, j]):
                return -1
    target = _matmul4(_matmul4(chain_T_base, base_T_tool), tool_T_flange)
    raw, n_raw = _puma_raw(target, lengths, signs, offsets, q_ref[3])
    if n_raw == 0:
        return 0
    return 1 if _nearest_of(raw, n_raw, q_ref, lower, upper, tolerance, respect_limits, out) else 0


def solve_ik_nearest(
    robot: Robot,
    base_T_tool: np.ndarray | None = None,
    q_seed: np.ndarray | None = None,
    *,
    position: np.ndarray | None = None,
    respect_limits: bool = True,
    limit_tolerance: float | None = None,
) -> np.ndarray | None:
    """The IK solution nearest ``q_seed`` (zeros if None): what ``solve_ik(...)[0]`` returns with
    the same arguments (``q_near=q_seed``), or None where that list is empty. ``base_T_tool`` is
    the tool pose (4, 4) in the base frame; ``position`` (3,) serves position-only robots."""
    desc = robot.description
    if desc.ik != "puma":
        sols = solve_ik(
            robot, base_T_tool, position=position, q_near=q_seed,
            respect_limits=respect_limits, limit_tolerance=limit_tolerance,
        )
        return sols[0] if sols else None
    hit = _PARAMS.get(id(desc))
    params = hit[1] if hit is not None and hit[0]() is desc else _puma_params(robot)
    # the common call (float64 arrays, the robot's own tolerance) goes straight to the kernel,
    # which checks shapes and finiteness; anything else is converted and checked here first
    if type(q_seed) is np.ndarray and q_seed.dtype is _F64 and q_seed.ndim == 1:
        q_ref = q_seed
    elif q_seed is None:
        q_ref = np.zeros(robot.dof)
    else:
        q_ref = robot.as_q(q_seed)
    if type(base_T_tool) is np.ndarray and base_T_tool.dtype is _F64 and base_T_tool.ndim == 2:
        target = base_T_tool
    elif base_T_tool is None:
        if position is None:
            raise InputError("inverse kinematics needs a target pose or position")
        raise InputError("the PUMA needs a full tool pose (position and orientation)")
    else:
        target = np.asarray(base_T_tool, dtype=float)
        if target.shape != (4, 4):
            raise InputError(f"the PUMA IK needs a finite (4, 4) flange pose, got shape {target.shape}")
    if limit_tolerance is None:
        tolerance = params.tolerance
    elif limit_tolerance >= 0.0:
        tolerance = max(float(limit_tolerance), LIMIT_TOLERANCE)
    else:
        raise InputError(f"the IK limit tolerance must be zero or more; got {limit_tolerance}")
    out = np.empty(robot.dof)
    found = puma_nearest_packed(target, params.packed, q_ref, robot.lower, robot.upper, tolerance, bool(respect_limits), out)
    if found > 0:
        return out
    if found == 0:
        return None
    if found == -2 or found == -4:
        robot.as_q(q_ref)  # raises the usual message (wrong length, NaN or infinity)
    raise InputError(f"the PUMA IK needs a finite (4, 4) flange pose, got shape {target.shape}")
