"""The nominal closed loop of the push benchmark (its ``step`` loop: wqp-daqp, the
feed-forward at the robot's best, step adjustment, no push) on several walks, with Gains
keywords: fallen, the largest orientation deviation, travelled / planned, re-plans, the walking
ticks whose solve failed and those the stack's ``landing_fallback`` solved (issue 30, sixteenth
and nineteenth sessions: the options' nominal walks beside main's).

    nice -n 5 python benchmarks/nominal_closed.py '{"ff_sagittal": 2}' walk10_wb turn_wb lateral_wb
    nice -n 5 python benchmarks/nominal_closed.py '{}' '{"accept": 0.02}' walk10_wb turn_wb

(a second JSON: SteppingParams keywords of the ``step`` loop.)
"""

from __future__ import annotations

import json
import sys

from pushes import loop_spec

from wbc import load_robot
from wbc.balance import best_compensate
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import simulate
from wbc.bench.physics import physics_entry, plan


def main() -> None:
    gains = json.loads(sys.argv[1])
    args = sys.argv[2:]
    stepping = json.loads(args.pop(0)) if args and args[0].startswith("{") else {}
    robot = load_robot("bioloid")
    ff = best_compensate(robot)
    entry = physics_entry("wqp-daqp", robot)
    for walk in args:
        rec = plan("wqp-daqp", walk, robot)
        ref = traj.build(walk, robot)
        spec, comp = loop_spec("step", entry, ref, stepping, gains, {}, ff, None, robot)
        r = simulate(rec, robot, compensate=comp, closed=spec)
        print(json.dumps({"walk": walk, "gains": gains, "stepping": stepping, "fell": r["fell"],
                          "dev_deg": round(r["orientation_dev_max_deg"], 2),
                          "dist": round(r["distance_ratio"], 3),
                          "replans": r.get("replans"), "failed_solves": r.get("failed_solves"),
                          "fallbacks": r.get("landing_fallbacks"),
                          "braced": r.get("braced_ticks")}), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
