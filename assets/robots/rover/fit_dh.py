"""Fit the link lengths L1..L5 of the seed-004 lunar-rover arm to the 11 rows of its Table 2.

The paper prints the DH frame (Table 1) with symbolic lengths and a table of joint angles with
the resulting position of the spectrometer centre C, but never the lengths themselves. This
script recovers them: it models Table 1 as a standard (Angeles) DH chain, adds the fixed
horizontal offset between Table 2's frame and the joint-1 axis (the data show joint 1 does not
pass through Table 2's origin), and solves the nonlinear least-squares problem with a small
Levenberg-Marquardt loop in numpy (several starts, best kept). It then checks the rounded values
written to ``robot.toml`` through the project's own loader.

Run: ``.venv/bin/python assets/robots/rover/fit_dh.py`` (prints the fit and per-row residuals).
"""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

# Seed 004, Table 2: joint angles (deg, the paper's sign) and point C (m) in the table's frame.
TABLE2_Q_DEG = np.array([
    [0, 0, 0], [-5, -5, -5], [-10, -10, -10], [-20, -20, -20], [-30, -30, -30], [-30, -30, -60],
    [-30, -30, -120], [-30, -30, -190], [-40, -30, -190], [-40, -40, -190], [-40, -70, -220],
], dtype=float)
TABLE2_P_M = np.array([
    [0.548, 0.038, -0.146], [0.559, 0.027, -0.154], [0.572, 0.013, -0.158], [0.608, -0.017, -0.156],
    [0.658, -0.041, -0.136], [0.714, -0.138, -0.131], [0.787, -0.264, 0.028], [0.740, -0.182, 0.257],
    [0.793, -0.141, 0.257], [0.751, -0.092, 0.319], [0.529, 0.173, 0.384],
])

# Adopted conventions (see FIT.md): DH angle theta_i = SIGN_i * q_i + OFFSET_i, Table 1's twists.
SIGN = np.array([-1.0, -1.0, -1.0])
OFFSET_DEG = np.array([-90.0, 0.0, 90.0])
ALPHA_DEG = np.array([90.0, 0.0, -90.0])
PARAM_NAMES = ("L1", "L2", "L3", "L4", "L5", "px", "py")


def _rz(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _std_dh(theta: float, d: float, a: float, alpha: float) -> np.ndarray:
    """Standard DH link transform Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([
        [ct, -st * ca, st * sa, a * ct],
        [st, ct * ca, -ct * sa, a * st],
        [0.0, sa, ca, d],
        [0.0, 0.0, 0.0, 1.0],
    ])


def point_c(params: np.ndarray, q_deg: np.ndarray) -> np.ndarray:
    """Point C in Table 2's frame for joint angles ``q_deg`` (3,) and ``params`` (7,)."""
    l1, l2, l3, l4, l5, px, py = params
    theta = np.radians(SIGN * q_deg + OFFSET_DEG)
    alpha = np.radians(ALPHA_DEG)
    table_T_c = np.eye(4)
    table_T_c[:2, 3] = (px, py)
    table_T_c = (
        table_T_c
        @ _std_dh(theta[0], -l1, 0.0, alpha[0])
        @ _std_dh(theta[1], 0.0, l2, alpha[1])
        @ _std_dh(theta[2], l5, -l4, alpha[2])
    )
    return (table_T_c @ np.array([0.0, 0.0, l3, 1.0]))[:3]


def residuals(params: np.ndarray) -> np.ndarray:
    """Stacked (33,) model-minus-table residuals in metres."""
    return np.concatenate([point_c(params, q) - p for q, p in zip(TABLE2_Q_DEG, TABLE2_P_M)])


def levenberg_marquardt(x0: np.ndarray, iterations: int = 200) -> np.ndarray:
    """Plain LM with a forward-difference Jacobian; enough for 7 unknowns and 33 equations."""
    x, lam = x0.astype(float), 1e-3
    r = residuals(x)
    for _ in range(iterations):
        jac = np.empty((r.size, x.size))
        for k in range(x.size):
            step = np.zeros_like(x)
            step[k] = 1e-7
            jac[:, k] = (residuals(x + step) - r) / 1e-7
        jtj, jtr = jac.T @ jac, jac.T @ r
        while True:
            dx = np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-12), -jtr)
            r_new = residuals(x + dx)
            if r_new @ r_new < r @ r:
                x, r, lam = x + dx, r_new, max(lam / 10.0, 1e-12)
                break
            lam *= 10.0
            if lam > 1e12:
                return x
        if np.max(np.abs(dx)) < 1e-12:
            break
    return x


def fit(starts: int = 20, seed: int = 4) -> np.ndarray:
    rng = np.random.default_rng(seed)
    best, best_cost = None, np.inf
    for _ in range(starts):
        x = levenberg_marquardt(rng.uniform(-0.6, 0.6, len(PARAM_NAMES)))
        cost = float(residuals(x) @ residuals(x))
        if cost < best_cost:
            best, best_cost = x, cost
    assert best is not None
    return best


def standard_errors(params: np.ndarray) -> np.ndarray:
    """1-sigma uncertainty of each parameter if Table 2's only error is its rounding to 1 mm
    (uniform, sigma = 1 mm / sqrt(12) per coordinate)."""
    r0 = residuals(params)
    jac = np.empty((r0.size, params.size))
    for k in range(params.size):
        step = np.zeros_like(params)
        step[k] = 1e-7
        jac[:, k] = (residuals(params + step) - r0) / 1e-7
    sigma = 1e-3 / np.sqrt(12.0)
    return sigma * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))


def _print_rows(title: str, model_p: np.ndarray) -> float:
    print(title)
    print(" row   q1     q2     q3   |  x_c     y_c     z_c  (Table 2, m) | residual (mm)")
    norms = np.linalg.norm(model_p - TABLE2_P_M, axis=1) * 1e3
    for i, (q, p, n) in enumerate(zip(TABLE2_Q_DEG, TABLE2_P_M, norms), start=1):
        print(f" {i:3d} {q[0]:6.0f} {q[1]:6.0f} {q[2]:6.0f} | {p[0]:7.3f} {p[1]:7.3f} {p[2]:7.3f} | {n:6.3f}")
    print(f" max {norms.max():.3f} mm, rms {np.sqrt(np.mean(norms ** 2)):.3f} mm")
    return float(norms.max())


def check_robot_file() -> float:
    """FK of the shipped ``robot.toml`` (through the project's loader) plus the recorded mount."""
    sys.path.insert(0, str(HERE.parents[2]))
    from shared.robots.loader import load_robot

    raw = tomllib.loads((HERE / "robot.toml").read_text(encoding="utf-8"))
    table_p_base = np.array(raw["fit"]["table2_p_base"]) * 1e-3
    robot = load_robot(HERE / "robot.toml")
    model_p = np.array([robot.fk(np.radians(q))[:3, 3] + table_p_base for q in TABLE2_Q_DEG])
    return _print_rows("robot.toml (rounded to 0.1 mm) through shared.robots.loader:", model_p)


def main() -> int:
    x = fit()
    print("Fitted (standard DH, theta = -q + offset, offsets -90/0/+90 deg):")
    for name, value, err in zip(PARAM_NAMES, x, standard_errors(x)):
        print(f"  {name:3s} = {value * 1e3:9.3f} mm  (+- {err * 1e3:.2f} mm from Table 2's rounding)")
    worst = _print_rows("Least-squares fit:", np.array([point_c(x, q) for q in TABLE2_Q_DEG]))
    worst_file = check_robot_file() if (HERE / "robot.toml").is_file() else 0.0
    return 0 if max(worst, worst_file) < 1.0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
