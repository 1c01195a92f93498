"""How far inside its limits a stress trial's start outside them can come (issue 17, item 9).

    python benchmarks/stress_outside.py --trials 1567 8832

For each trial (drawn as ``benchmarks/stress.py`` draws it): the least joint-limit excess
(sum over the joints of how far each is outside its range, rad) of any configuration that
meets the trial's hard contacts as made at its start — SLSQP (scipy) minimising the squared
excess subject to the contacts, from the start and from ``--starts`` − 1 random perturbations
of its joints (kinematics only: no collision rows, no servo speed, so a lower bound on what a
controller can reach) — beside where ``--ticks`` control ticks of the trial's solver stop
(its targets as made at the start: the stress run's offsets are not applied).
A least excess above 0 from every start says the contacts as given cannot be met with every
joint inside its range.
"""

from __future__ import annotations

import argparse

import numpy as np
import stress  # benchmarks/stress.py: its draws and stacks (the script's folder is on the path)
from scipy.optimize import minimize

from wbc import Kinematics, load_robot
from wbc.model import Robot


def excess(robot: Robot, q: np.ndarray) -> np.ndarray:
    """How far (rad) each joint of q is outside its range (0 inside)."""
    j = q[7:]
    return np.maximum(robot.q_min - j, 0.0) + np.maximum(j - robot.q_max, 0.0)


def least_excess(robot: Robot, q0: np.ndarray, contacts: list, starts: int) -> list[tuple]:
    """(excess sum, largest contact error) of SLSQP's minimum from each start."""
    rng = np.random.default_rng(0)
    nv = robot.nv
    results = []
    for s in range(starts):
        v0 = np.zeros(nv)
        if s:
            v0[6:] = rng.uniform(-0.3, 0.3, nv - 6)

        def errors(v: np.ndarray) -> np.ndarray:
            kin = Kinematics(robot, robot.integrate(q0, v))
            return np.concatenate([c.compute_error(kin) for c in contacts])

        r = minimize(
            lambda v: float((excess(robot, robot.integrate(q0, v)) ** 2).sum()), v0,
            constraints=[{"type": "eq", "fun": errors}], method="SLSQP",
            options={"maxiter": 500, "ftol": 1e-14},
        )  # fmt: skip
        results.append((excess(robot, robot.integrate(q0, r.x)).sum(), abs(errors(r.x)).max()))
    return results


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, nargs="+", required=True)
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--ticks", type=int, default=50)
    ap.add_argument("--seed", type=int, default=2024)
    args = ap.parse_args()
    robot = load_robot("bioloid")
    for trial in args.trials:
        p = stress.draw(robot, np.random.default_rng([args.seed, trial]), ["daqp"])
        q0 = stress.start(robot, p)
        if p["stack"] != "walk" or not p["double"]:
            print(f"trial {trial}: not a double-support walk-stack trial")
            continue
        compiled = None if p["compiled"] else False
        solver, contacts, *_ = stress.walk_stack(robot, q0, p["kind"], "daqp", compiled, True)
        found = least_excess(robot, q0, contacts, args.starts)
        q = q0
        for _ in range(args.ticks):
            q = solver.step(q, 0.01)
        print(
            f"trial {trial}: excess at the start {excess(robot, q0).sum():.4f} rad; least with "
            f"the contacts met, {args.starts} starts: "
            f"{min(e for e, _ in found):.4f}..{max(e for e, _ in found):.4f} rad (contacts "
            f"within {max(c for _, c in found):.1e}); after {args.ticks} ticks "
            f"{excess(robot, q).sum():.4f} rad"
        )


if __name__ == "__main__":
    main()
