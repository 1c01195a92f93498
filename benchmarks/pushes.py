"""Pushes at mid single support: open loop vs closed loop vs closed loop + stepping.

The largest 10 ms torso impulse survived (N·s, bisection over 0–3 N·s as ``wbc bench
--physics --push``: :func:`wbc.bench.physics.largest_push`), on ``walk10``, per solver, for
the plan played open loop, the closed loop (compliance ×0.5) and the closed loop with step
placement from the measured DCM (:mod:`wbc.balance.stepping`); plus the nominal run's
figures and the LIPM capturability bounds (:func:`wbc.balance.stepping.capture_bounds`).

    python benchmarks/pushes.py --solvers wqp-daqp hqp-daqp placo pink --json pushes.json
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
    args = ap.parse_args()
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


if __name__ == "__main__":
    main()
