"""Kokone closed loop through the IMU and the commanded joints: which stabilizer gains.

    python benchmarks/kokone_closed_loop.py                   # benchmarks/kokone_sim.md sec. 00
    python benchmarks/kokone_closed_loop.py --gains open sized default   # section 0000
    python benchmarks/kokone_closed_loop.py --models 5 --gains open soft --trajectories walk10
    python benchmarks/kokone_closed_loop.py --gains soft --stack my_walk.toml   # another stack

Each trajectory is planned once by ``hqp-daqp`` (the robot folder's stack), then run as
``wbc bench --physics --robot kokone`` does (feed-forward at ``best_compensate``, ×1 on hobby
servos): ``open`` plays the plan; the others run the controller live, closed through the
simulated IMU and the commanded joints (its servos report no position) with step adjustment,
under the named :class:`~wbc.balance.stabilizer.Gains`. Per row: the nominal run (fell at, s;
travelled / planned distance) and the share of ``--models`` randomised plants (seed 0) that
stay up.
"""

from __future__ import annotations

import argparse
import json
import time

from wbc.balance import best_compensate
from wbc.balance.stabilizer import Gains
from wbc.balance.stepping import SteppingParams
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import ClosedLoopSpec, robustness, simulate
from wbc.bench.physics import physics_stack
from wbc.bench.runner import run_entry
from wbc.bench.solvers import select
from wbc.model import load_robot

GAINS = {
    "sized": None,  # the closed loop's default: Gains() sized to the servos (wbc.balance.margin)
    "default": Gains(),  # the design robot's gains as they are
    "nohip": Gains(k_hip=0),
    "soft": Gains(k_hip=0, k_p=0.3, k_i=0.3, k_d=0.0),
    "softhip": Gains(k_p=0.3, k_i=0.3, k_d=0.0),
    "vsoft": Gains(k_hip=0, k_p=0.15, k_i=0.1, k_d=0.0),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trajectories", nargs="+", default=["keyposes", "walk10"])
    parser.add_argument("--gains", nargs="+", default=["open", *GAINS],
                        choices=["open", *GAINS])  # fmt: skip
    parser.add_argument("--models", type=int, default=20)
    parser.add_argument("--stack", help="the stack (default: the robot folder's)")
    args = parser.parse_args()
    robot = load_robot("kokone")
    entries, _ = select(["hqp-daqp"], None, "tick", stack=physics_stack(robot, args.stack))
    entry = next(e for e in entries if e.name == "hqp-daqp")
    comp = best_compensate(robot)
    for name in args.trajectories:
        ref = traj.build(name, robot)
        _, rec = run_entry(entry, robot, ref, "tick")
        for k in args.gains:
            spec = None
            if k != "open":
                spec = ClosedLoopSpec(entry.make, ref, GAINS[k], True, True, SteppingParams())
            t0 = time.perf_counter()
            r = simulate(rec, robot, None, compensate=comp, closed=spec)
            rob = robustness(rec, robot, args.models, 0, compensate=comp, closed=spec)
            row = {"trajectory": name, "loop": k, "fell_s": r.get("fall_time_s"),
                   "distance": r.get("distance_ratio"), "up_fraction": rob["up_fraction"],
                   "wall_s": round(time.perf_counter() - t0, 1)}  # fmt: skip
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
