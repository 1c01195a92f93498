"""Kokone leg IK: our hierarchical QP against the thesis's genetic algorithm on 30 poses.

The thesis (kokone-thesis.md §2.7, §5) solves each leg's IK with a GA: real genes in the Table
4.3 bounds, roulette selection, two-point crossover (p_c = 0.7), Gaussian mutation around the
best individual (p_m = 0.3, σ = 0.1 while the best fitness ≥ 1, else fitness / 1.5), elitism,
stop at fitness ≤ 0.001 or 8,000 generations, up to 5 restarts. Its fitness is the norm of
the 4x4 matrix difference (eqs. 4.41/4.42; taken here as the Frobenius norm, lengths in cm).
Tables 4.4/4.5 report that fitness on 30 poses (30 runs each) but neither the poses nor any
time: the 30 poses are regenerated here as *reachable* targets (both legs' angles drawn in
the Table 4.3 bounds shrunk by 5°, the hip at a random height 20-21.8 cm and offset ±1 cm;
the feet where forward kinematics puts them), seeded, so every target has an exact answer.

Ours: :class:`wbc.pose_ik.StanceIK` (torso and both soles as 6-D pose tasks, joint limits as
hard bounds, Gauss-Newton iterations of the hierarchical QP to 1e-11), from the crouch. The GA
here is this script's reimplementation of the thesis's Algorithms 1-3 (population 100: the
thesis does not give one), only as a baseline; it runs ``--ga-runs`` times per pose and leg.

Run: ``python benchmarks/kokone_ik.py [--ga-runs 3] [--restarts 5] [--out FILE]``
"""

from __future__ import annotations

import argparse
import importlib.util
import platform
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from wbc import load_robot  # noqa: E402
from wbc.pose_ik import StanceIK  # noqa: E402

CM = 0.01
spec = importlib.util.spec_from_file_location("kokone_gen", ROOT / "robots/kokone/make_urdf.py")
gen = importlib.util.module_from_spec(spec)
spec.loader.exec_module(gen)

LO = np.array([lo for lo, _ in gen.DH_RANGE_DEG], dtype=float)
HI = np.array([hi for _, hi in gen.DH_RANGE_DEG], dtype=float)


def leg_fk(theta_deg: np.ndarray, right: bool) -> np.ndarray:
    """A_CD / A_CI (eqs. 4.31/4.32) for a batch (N, 6) of DH angles: (N, 4, 4), cm."""
    th = np.radians(np.atleast_2d(theta_deg))
    n = th.shape[0]
    A = np.tile(np.eye(4), (n, 1, 1))
    A[:, 1, 3] = 2.25 if right else -2.25
    for k, (d, a, al) in enumerate(gen.DH_TABLE):
        c, s = np.cos(th[:, k]), np.sin(th[:, k])
        ca, sa = np.cos(np.radians(al)), np.sin(np.radians(al))
        T = np.zeros((n, 4, 4))
        T[:, 0, 0], T[:, 0, 1], T[:, 0, 2], T[:, 0, 3] = c, -ca * s, sa * s, a * c
        T[:, 1, 0], T[:, 1, 1], T[:, 1, 2], T[:, 1, 3] = s, ca * c, -sa * c, a * s
        T[:, 2, 1], T[:, 2, 2], T[:, 2, 3] = sa, ca, d
        T[:, 3, 3] = 1.0
        A = A @ T
    return A


def fitness(theta_deg: np.ndarray, target: np.ndarray, right: bool) -> np.ndarray:
    """‖A_mc⁻¹ A_Pie − A_C(θ)‖_F (the thesis's eqs. 4.41/4.42), per individual."""
    return np.linalg.norm(leg_fk(theta_deg, right) - target, axis=(1, 2))


def ga(target, right, rng, pop=100, generations=8000, restarts=5, tol=1e-3):
    """The thesis's GA (Algorithms 1-3) for one leg: (best θ, best fitness, generations)."""
    best_t, best_f, gens = None, np.inf, 0
    for _ in range(1 + restarts):
        X = LO + rng.random((pop, 6)) * (HI - LO)
        F = fitness(X, target, right)
        for _g in range(generations):
            gens += 1
            b = int(np.argmin(F))
            if F[b] <= tol:
                break
            elite, elite_f = X[b].copy(), F[b]
            w = 1.0 / (F + 1e-12)  # roulette on 1/fitness (the thesis leaves this open)
            X = X[rng.choice(pop, pop, p=w / w.sum())]
            pairs = rng.permutation(pop).reshape(-1, 2)  # two-point crossover, p_c = 0.7
            cuts = np.sort(rng.integers(0, 7, (len(pairs), 2)), axis=1)
            cols = np.arange(6)
            swap = (cols >= cuts[:, :1]) & (cols < cuts[:, 1:])
            swap &= (rng.random(len(pairs)) < 0.7)[:, None]
            xi, xj = X[pairs[:, 0]], X[pairs[:, 1]]
            X[pairs[:, 0]], X[pairs[:, 1]] = np.where(swap, xj, xi), np.where(swap, xi, xj)
            sigma = 0.1 if elite_f >= 1.0 else elite_f / 1.5
            sigma_deg = np.degrees(sigma)
            mask = rng.random((pop, 6)) < 0.3
            X = np.where(mask, elite + rng.normal(0, sigma_deg, (pop, 6)), X)
            X = np.clip(X, LO, HI)
            X[0] = elite  # elitism
            F = fitness(X, target, right)
        b = int(np.argmin(F))
        if F[b] < best_f:
            best_t, best_f = X[b].copy(), F[b]
        if best_f <= tol:
            break
    return best_t, float(best_f), gens


def poses(n: int = 30, seed: int = 2009) -> list[dict]:
    """Reachable targets: leg angles in Table 4.3 shrunk by 5°, hip upright at a random spot."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        th = {s: LO + 5 + rng.random(6) * (HI - LO - 10) for s in ("r", "l")}
        hip = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(20.0, 21.8)])
        out.append({"theta": th, "hip": hip})
    return out


def world_targets(pose: dict) -> tuple[dict[str, pin.SE3], dict[str, np.ndarray]]:
    """Torso and sole placements (m) in the world; the hip-frame targets A_C (cm) per leg."""
    A_mc = np.eye(4)
    A_mc[:3, :3] = gen.R_MC
    A_mc[:3, 3] = pose["hip"]
    targets = {"torso": pin.SE3(np.eye(3), pose["hip"] * CM)}
    hip_frame = {}
    for s, right in (("r", True), ("l", False)):
        A_c = leg_fk(pose["theta"][s], right)[0]
        hip_frame[s] = A_c
        world = A_mc @ A_c
        # the thesis's foot frame has the hip frame's axes; our sole frame the torso's
        targets[f"{s}_sole"] = pin.SE3(world[:3, :3] @ gen.R_MC.T, world[:3, 3] * CM)
    return targets, hip_frame


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ga-runs", type=int, default=3, help="GA runs per pose and leg")
    ap.add_argument("--generations", type=int, default=8000)
    ap.add_argument("--restarts", type=int, default=5, help="GA restarts (thesis: up to 5)")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    robot = load_robot("kokone")
    ik = StanceIK(robot)
    q0 = robot.configuration("stand")
    ik.solve(world_targets(poses()[0])[0], q0)  # warm-up (numba compile, layouts)
    rng = np.random.default_rng(1)
    rows = []
    for k, pose in enumerate(poses(), 1):
        targets, hip_frame = world_targets(pose)
        t0 = time.perf_counter()
        res = ik.solve(targets, q0)
        ours_t = time.perf_counter() - t0
        ours_fit = max(
            float(
                fitness(
                    gen.q_to_dh([res.q[robot.q_index(f"{s}_{n}")] for n in gen.LEG_JOINTS]),
                    hip_frame[s],
                    s == "r",
                )[0]
            )
            for s in "rl"
        )
        ga_fit, ga_t, ga_fail = [], [], 0
        for _ in range(args.ga_runs):
            for s in "rl":
                t0 = time.perf_counter()
                _, f, _ = ga(
                    hip_frame[s],
                    s == "r",
                    rng,
                    generations=args.generations,
                    restarts=args.restarts,
                )
                ga_t.append(time.perf_counter() - t0)
                ga_fit.append(f)
                ga_fail += f > 1e-3
        rows.append(
            (k, ik.residual(res.q, targets), ours_fit, res.iterations, ours_t, res.converged,
             float(np.mean(ga_fit)), float(np.max(ga_fit)), ga_fail, len(ga_fit),
             float(np.median(ga_t)))
        )  # fmt: skip
        print(
            f"pose {k:2d}: ours {rows[-1][2]:.1e} in {ours_t * 1e3:.2f} ms; GA mean "
            f"{rows[-1][6]:.1e}, {ga_fail}/{len(ga_fit)} > 0.001, {rows[-1][10]:.2f} s",
            flush=True,
        )
    lines = [
        f"machine: {platform.machine()} {platform.processor() or ''}, Python "
        f"{platform.python_version()}; GA runs per pose and leg: {args.ga_runs}, "
        f"generations {args.generations}, restarts {args.restarts}",
        "",
        "| pose | ours: pose residual (m, rad) | ours: fitness | iterations | ours ms | "
        "GA fitness mean / worst | GA runs > 0.001 | GA s per leg (median) | GA time / ours |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for k, res_err, fit, it, t, conv, gm, gw, fail, n, gt in rows:
        lines.append(
            f"| {k} | {res_err:.1e}{'' if conv else ' (not converged)'} | {fit:.1e} | {it} | "
            f"{t * 1e3:.2f} | {gm:.1e} / {gw:.1e} | {fail}/{n} | {gt:.2f} | {gt / t:.0f}× |"
        )
    a = np.array([(r[1], r[2], r[4], r[8], r[9], r[10], r[10] / r[4]) for r in rows])
    lines += [
        "",
        f"ours: worst residual {a[:, 0].max():.1e}, worst fitness {a[:, 1].max():.1e}, "
        f"{sum(r[5] for r in rows)}/30 converged, median {np.median(a[:, 2]) * 1e3:.2f} ms "
        f"per pose (both legs)",
        f"GA: {int(a[:, 3].sum())}/{int(a[:, 4].sum())} runs above 0.001, median "
        f"{np.median(a[:, 5]):.2f} s per leg; GA time per leg / our time per pose (both legs): "
        f"median {np.median(a[:, 6]):.0f}×",
    ]
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
