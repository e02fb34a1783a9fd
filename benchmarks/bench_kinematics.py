"""Kinematics benchmark: FK, Jacobian and IK (cold and warm goals) for the PUMA 562.

Also the nearest-solution IK that jogging calls (``solve_ik_nearest``, one compiled call),
seeded as jogging seeds it: from the previous step of a smooth joint path.

Compares this project's closed-form IK with pinocchio's own numeric IK loop (the CLIK example of
pinocchio's documentation: log6 error, frame Jacobian, damped pseudo-inverse, integrate) and
with ikpy (an established PyPI IK solver) on the same goals. Prints a table and, with --json,
machine-readable figures. Run: .venv/bin/python benchmarks/bench_kinematics.py
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from shared.robots.ik import solve_ik
from shared.robots.ik_kernels import solve_ik_nearest
from shared.robots.loader import load_robot
from shared.spatial import matrix_to_rpy

ROBOT = load_robot("puma562")


def random_q(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform(ROBOT.lower, ROBOT.upper, size=(n, ROBOT.dof))


def timed(fn: Callable[[], object], repeat: int = 1) -> float:
    """Best of ``repeat`` wall times of ``fn`` (s)."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def smooth_path(rng: np.random.Generator, n: int, step_deg: float = 0.5) -> np.ndarray:
    """``n`` joint vectors (n, dof) of a random smooth walk inside the ranges: each joint moves
    about ``step_deg`` per step, turning back at its limits (a jog drag's successive targets)."""
    lo, hi = ROBOT.lower + 0.05, ROBOT.upper - 0.05
    q = np.empty((n, ROBOT.dof))
    q[0] = rng.uniform(lo, hi)
    velocity = rng.choice([-1.0, 1.0], size=ROBOT.dof) * np.radians(step_deg)
    for i in range(1, n):
        velocity = velocity + rng.normal(0.0, np.radians(step_deg) * 0.1, size=ROBOT.dof)
        velocity = np.clip(velocity, -np.radians(step_deg), np.radians(step_deg))
        nxt = q[i - 1] + velocity
        bounce = (nxt < lo) | (nxt > hi)
        velocity[bounce] *= -1.0
        q[i] = np.clip(q[i - 1] + velocity, lo, hi)
    return q


def pinocchio_clik(target: pin.SE3, q0: np.ndarray, data: pin.Data, eps: float = 1e-9, it_max: int = 1000) -> tuple[np.ndarray, bool]:
    """Pinocchio's documented CLIK loop on the tool frame (damped pseudo-inverse, step 0.1... 1)."""
    model, fid = ROBOT.model, ROBOT.tool_frame_id
    q = q0.copy()
    damp, dt = 1e-12, 1.0
    for _ in range(it_max):
        pin.framesForwardKinematics(model, data, q)
        err_se3 = data.oMf[fid].actInv(target)
        err = pin.log6(err_se3).vector
        if np.linalg.norm(err) < eps:
            return q, True
        jac = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
        jac = -pin.Jlog6(err_se3.inverse()) @ jac
        v = -jac.T @ np.linalg.solve(jac @ jac.T + damp * np.eye(6), err)
        q = pin.integrate(model, q, v * dt)
    return q, False


def make_ikpy_chain():
    from ikpy.chain import Chain
    from ikpy.link import OriginLink, URDFLink

    links = [OriginLink()]
    for i in range(1, ROBOT.dof + 1):
        placement = ROBOT.model.jointPlacements[i]
        links.append(
            URDFLink(
                name=f"joint{i}", origin_translation=np.array(placement.translation),
                origin_orientation=matrix_to_rpy(placement.rotation), rotation=np.array([0.0, 0.0, 1.0]),
                bounds=(float(ROBOT.lower[i - 1]), float(ROBOT.upper[i - 1])),
            )
        )
    return Chain(links, active_links_mask=[False] + [True] * ROBOT.dof)


def run(n_goals: int, n_batch: int, with_ikpy: bool, seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    qs = random_q(rng, n_batch)
    data = ROBOT.new_data()
    out: dict[str, dict[str, float]] = {}

    t = timed(lambda: [ROBOT.fk(q, data) for q in qs], 3)
    out["fk"] = {"per_call_us": t / n_batch * 1e6, "batch_10k_ms": t / n_batch * 1e4 * 1e3}
    t = timed(lambda: [ROBOT.jacobian(q, data) for q in qs], 3)
    out["jacobian"] = {"per_call_us": t / n_batch * 1e6, "batch_10k_ms": t / n_batch * 1e4 * 1e3}

    goals_q = random_q(rng, n_goals)
    goals = [ROBOT.fk(q, data).copy() for q in goals_q]
    # warm goals: a small step (about 1 deg per joint) from a known configuration
    warm_from = goals_q + rng.normal(0.0, np.radians(1.0), size=goals_q.shape)
    warm_from = np.clip(warm_from, ROBOT.lower, ROBOT.upper)

    def ours_cold() -> int:
        return sum(bool(solve_ik(ROBOT, g)) for g in goals)

    def ours_warm() -> int:
        return sum(bool(solve_ik(ROBOT, g, q_near=q0)) for g, q0 in zip(goals, warm_from))

    def clik(seeds: np.ndarray) -> int:
        return sum(pinocchio_clik(pin.SE3(g[:3, :3], g[:3, 3]), s, data)[1] for g, s in zip(goals, seeds))

    def ours_nearest() -> int:
        return sum(solve_ik_nearest(ROBOT, g, q0) is not None for g, q0 in zip(goals, warm_from))

    # a smooth path (what a jog drag produces): each goal is FK of the next point, seeded from
    # the previous point's joints; the closed form and CLIK are run on the same path
    path_q = smooth_path(rng, n_goals)
    path_goals = [ROBOT.fk(q, data).copy() for q in path_q]

    def path_nearest() -> int:
        return sum(solve_ik_nearest(ROBOT, g, q0) is not None for g, q0 in zip(path_goals[1:], path_q[:-1]))

    def path_clik() -> int:
        return sum(
            pinocchio_clik(pin.SE3(g[:3, :3], g[:3, 3]), q0, data)[1] for g, q0 in zip(path_goals[1:], path_q[:-1])
        )

    solve_ik_nearest(ROBOT, goals[0], warm_from[0])  # compile (or load the cache) outside the timing
    neutral = np.tile(pin.neutral(ROBOT.model), (n_goals, 1))
    for name, fn in [
        ("ik_cold_closed_form", ours_cold),
        ("ik_warm_closed_form", ours_warm),
        ("ik_cold_pinocchio_clik", lambda: clik(neutral)),
        ("ik_warm_pinocchio_clik", lambda: clik(warm_from)),
        ("ik_warm_nearest", ours_nearest),
        ("ik_path_nearest", path_nearest),
        ("ik_path_pinocchio_clik", path_clik),
    ]:
        calls = n_goals - 1 if name.startswith("ik_path") else n_goals
        t0 = time.perf_counter()
        ok = fn()
        t = time.perf_counter() - t0
        out[name] = {"per_call_us": t / calls * 1e6, "batch_10k_ms": t / calls * 1e4 * 1e3, "success": ok / calls}

    if with_ikpy:
        chain = make_ikpy_chain()
        m = min(n_goals, 100)  # ikpy is slow: a subset of the same goals
        for name, seeds in [("ik_cold_ikpy", np.zeros((m, ROBOT.dof))), ("ik_warm_ikpy", warm_from[:m])]:
            ok = 0
            t0 = time.perf_counter()
            for g, s in zip(goals[:m], seeds):
                sol = chain.inverse_kinematics(g[:3, 3], g[:3, :3], orientation_mode="all", initial_position=np.r_[0.0, s])
                ok += bool(np.allclose(ROBOT.fk(sol[1:], data), g, atol=1e-4))
            t = time.perf_counter() - t0
            out[name] = {"per_call_us": t / m * 1e6, "batch_10k_ms": t / m * 1e4 * 1e3, "success": ok / m}

    for name, peer in (("ik_warm_nearest", "ik_warm_pinocchio_clik"), ("ik_path_nearest", "ik_path_pinocchio_clik")):
        out[name]["speedup_vs_pinocchio_clik"] = out[peer]["per_call_us"] / out[name]["per_call_us"]
    for kind in ("cold", "warm"):
        ours = out[f"ik_{kind}_closed_form"]["per_call_us"]
        out[f"ik_{kind}_closed_form"]["speedup_vs_pinocchio_clik"] = out[f"ik_{kind}_pinocchio_clik"]["per_call_us"] / ours
        if with_ikpy:
            out[f"ik_{kind}_closed_form"]["speedup_vs_ikpy"] = out[f"ik_{kind}_ikpy"]["per_call_us"] / ours
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--goals", type=int, default=1000)
    parser.add_argument("--batch", type=int, default=10000)
    parser.add_argument("--no-ikpy", action="store_true")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    result = run(args.goals, args.batch, not args.no_ikpy)
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"{'measure':28s} {'per call':>12s} {'per 10k':>12s} {'success':>8s}  ratio")
    for name, row in result.items():
        ratio = " ".join(f"{k.removeprefix('speedup_vs_')}: {v:.1f}x" for k, v in row.items() if k.startswith("speedup"))
        success = f"{row['success'] * 100:.1f}%" if "success" in row else ""
        print(f"{name:28s} {row['per_call_us']:9.1f} us {row['batch_10k_ms']:9.1f} ms {success:>8s}  {ratio}")


if __name__ == "__main__":
    main()
