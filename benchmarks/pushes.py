"""Pushes at mid single support: open loop vs closed loop vs closed loop + stepping.

The largest 10 ms torso impulse survived (N·s, bisection over 0–3 N·s as ``wbc bench
--physics --push``: :func:`wbc.bench.physics.largest_push`), on ``walk10``, per solver, for
the plan played open loop, the closed loop (compliance ×0.5) and the closed loop with step
placement from the measured DCM (:mod:`wbc.balance.stepping`); plus the nominal run's
figures and the LIPM capturability bounds (:func:`wbc.balance.stepping.capture_bounds`).

    python benchmarks/pushes.py --solvers wqp-daqp hqp-daqp placo pink --json pushes.json
    python benchmarks/pushes.py --solvers wqp-daqp --safety 0.83   # goals at one push
    python benchmarks/pushes.py --solvers wqp-daqp --grid 0.7 0.95 0.025  # survival per impulse
"""

from __future__ import annotations

import argparse
import json
import time

from wbc.balance.stabilizer import Gains
from wbc.balance.stepping import SteppingParams, capture_bounds
from wbc.bench import trajectories as traj
from wbc.bench.physics import ClosedLoopSpec, largest_push, plan, simulate
from wbc.bench.solvers import select
from wbc.model import load_robot
from wbc.walking.legs import LegGeometry


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solvers", nargs="+", default=["wqp-daqp", "hqp-daqp", "placo", "pink"])
    ap.add_argument("--loops", nargs="+", default=["open", "closed", "step"])
    ap.add_argument("--directions", nargs="+", default=["lateral", "forward"])
    ap.add_argument("--trajectory", default="walk10")
    ap.add_argument("--json", default=None)
    ap.add_argument(
        "--safety",
        type=float,
        default=None,
        metavar="NS",
        help="instead: one lateral push of NS N·s per closed loop; the goals' excursions "
        "beyond the joint limits, clamped and rate-limited ticks",
    )
    ap.add_argument(
        "--grid",
        type=float,
        nargs=3,
        metavar=("FROM", "TO", "STEP"),
        help="instead: survive or fall at every lateral impulse of the grid (N·s), per loop",
    )
    args = ap.parse_args()
    if args.grid is not None:
        grid(args)
        return
    if args.safety is not None:
        safety(args)
        return
    robot = load_robot("bioloid")
    ref = traj.build(args.trajectory, robot)
    legs = LegGeometry.from_robot(robot, robot.configuration("stand"))
    bounds = capture_bounds(ref, robot.total_mass, legs)
    print(json.dumps(bounds, indent=1))
    out = {"bounds": bounds, "runs": []}
    for solver in args.solvers:
        entries, _ = select([solver], None, "tick")
        entry = next(e for e in entries if e.name == solver)
        rec = plan(solver, args.trajectory, robot)
        for loop in args.loops:
            spec = None
            if loop != "open":
                step = SteppingParams() if loop == "step" else None
                spec = ClosedLoopSpec(entry.make, ref, Gains(), True, True, step)
            comp = 0.0 if loop == "open" else 0.5
            started = time.perf_counter()
            nominal = simulate(rec, robot, compensate=comp, closed=spec)
            row = {"solver": solver, "loop": loop, "compensate": comp,
                   "fell": nominal["fell"], "dev_deg": nominal["orientation_dev_max_deg"],
                   "dist": nominal["distance_ratio"], "replans": nominal.get("replans"),
                   "goal_limit_excess_deg": nominal.get("goal_limit_excess_deg"),
                   "share": nominal.get("feedback_share")}  # fmt: skip
            for d in args.directions:
                row[f"push_{d}_ns"] = largest_push(rec, robot, d, compensate=comp, closed=spec)
            row["wall_s"] = time.perf_counter() - started
            print(json.dumps(row), flush=True)
            out["runs"].append(row)
            if args.json:
                with open(args.json, "w") as f:
                    json.dump(out, f, indent=1)


def grid(args) -> None:
    """Up (1) or fallen (0) at each lateral impulse of the grid, per solver and loop: the
    bisection of ``--push`` assumes one threshold; stepping makes survival non-monotonic."""
    import numpy as np

    from wbc.bench.physics import PUSH_DURATION, mid_single_support, push_direction

    robot = load_robot("bioloid")
    ref = traj.build(args.trajectory, robot)
    lo, hi, step = args.grid
    impulses = np.round(np.arange(lo, hi + 1e-9, step), 4)
    for solver in args.solvers:
        entry = next(e for e in select([solver], None, "tick")[0] if e.name == solver)
        rec = plan(solver, args.trajectory, robot)
        u, t = push_direction(rec, "lateral"), mid_single_support(rec)
        for loop in args.loops:
            spec = None
            if loop != "open":
                stepping = SteppingParams() if loop == "step" else None
                spec = ClosedLoopSpec(entry.make, ref, Gains(), True, True, stepping)
            comp = 0.0 if loop == "open" else 0.5
            up = []
            for j in impulses:
                push = (t, u * j / PUSH_DURATION, PUSH_DURATION)
                up.append(int(not simulate(rec, robot, push=push, compensate=comp,
                                           closed=spec)["fell"]))  # fmt: skip
            row = {"solver": solver, "loop": loop, "impulses": impulses.tolist(), "up": up}
            print(json.dumps(row), flush=True)


def safety(args) -> None:
    """The deployment's view of the goals of one pushed run per closed loop."""
    import numpy as np

    from wbc.bench.physics import (
        PUSH_DURATION,
        mid_single_support,
        physics_record,
        play_closed_loop,
        push_direction,
    )

    robot = load_robot("bioloid")
    ref = traj.build(args.trajectory, robot)
    for solver in args.solvers:
        entry = next(e for e in select([solver], None, "tick")[0] if e.name == solver)
        rec = plan(solver, args.trajectory, robot)
        u = push_direction(rec, "lateral")
        push = (mid_single_support(rec), u * args.safety / PUSH_DURATION, PUSH_DURATION)
        for loop in ("closed", "step"):
            step = SteppingParams() if loop == "step" else None
            spec = ClosedLoopSpec(entry.make, ref, Gains(), True, True, step)
            result, cl = play_closed_loop(spec, robot, push=push, compensate=0.5)
            rec_fig = physics_record(rec, result, robot, ref)
            lim = result.deploy.limits
            row = {
                "solver": solver,
                "loop": loop,
                "impulse_ns": args.safety,
                "fell": rec_fig["fell"],
                "replans": len(cl.stepping.events) if cl.stepping else None,
                "goal_limit_excess_deg": float(np.degrees(max(cl.source.limit_excess, 0.0))),
                "clamped_ticks": int(lim.clamped.sum()),
                "rate_limited_ticks": int(lim.rate_limited.sum()),
                "rate_limited_max_joint": int(lim.rate_limited.max()),
                "completed": bool(result.deploy.completed),
            }
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
