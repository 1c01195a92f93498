"""Trace a walk in the simulator on two stacks side by side: why one falls where the other
stands (benchmarks/balance.md, "Fifth follow-up"). Open loop with the compliance feed-forward
(``--compensate``, default 1: Kokone's default), as ``wbc bench --physics --open-loop``.

    python benchmarks/switch_trace.py --robot kokone --walk static_walk \\
        --stacks robots/kokone/stack.toml tasks/walk.toml --start 6.5 --end 8.3

For each stack: the fall (time, most loaded joint) or the largest deviation; then every
``--every`` ticks in [start, end] s: the support, the torso's roll and pitch (deg, the plan's
in brackets), the soles' normal forces (N, left / right) and the three largest joint tracking
errors (deg); then the two plans' largest joint differences (deg) over the same window.
"""

from __future__ import annotations

import argparse

import numpy as np
import pinocchio as pin

from wbc.bench.play import play
from wbc.bench.sim_record import _planned, physics_record
from wbc.bench.trajectories import build
from wbc.model import load_robot
from wbc.stacks import load_stack
from wbc.walking.loop import StackController, run


def _rpy(q: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (deg) of the base of each configuration in ``q``."""
    return np.degrees([pin.rpy.matrixToRpy(pin.Quaternion(x[3:7]).toRotationMatrix()) for x in q])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="kokone")
    parser.add_argument("--walk", default="static_walk")
    parser.add_argument("--stacks", nargs=2, required=True, metavar="STACK")
    parser.add_argument("--start", type=float, default=0.0, help="s from the playback's start")
    parser.add_argument("--end", type=float, default=1e9)
    parser.add_argument("--every", type=int, default=5, help="print every N ticks")
    parser.add_argument("--compensate", type=float, default=1.0)
    args = parser.parse_args()
    robot = load_robot(args.robot)
    ref = build(args.walk, robot)
    names = robot.joint_names
    plans = []
    for stack in args.stacks:
        rec = run(StackController(load_stack(stack, robot)), robot, ref)
        plans.append(rec)
        res = play(rec, robot, settle=1.0, limit_tol=np.inf, compensate=args.compensate)
        r = physics_record(rec, res, robot, ref)
        fell = f"fell {r['fall_time_s']:.2f} s ({r['fall_joint']})" if r["fell"] else "up"
        print(f"{stack}: {fell}, dev {r['orientation_dev_max_deg']:.1f} deg")
        t = res.log["t"] - res.playback_start
        q, plan = res.log["q"], _planned(rec, t)
        rec_t = rec.t - rec.t[0]
        sup = rec.channels["support"][
            np.clip(np.searchsorted(rec_t, t, side="right") - 1, 0, len(rec_t) - 1)
        ]
        real, planned = _rpy(q), _rpy(plan)
        force = res.log["sole_force"]
        window = np.flatnonzero((t >= args.start) & (t <= args.end))[:: args.every]
        for k in window:
            err = np.degrees(q[k, 7:] - plan[k, 7:])
            worst = np.argsort(-np.abs(err))[:3]
            print(
                f"  t {t[k]:5.2f} support {sup[k]} roll {real[k, 0]:6.1f} ({planned[k, 0]:5.1f}) "
                f"pitch {real[k, 1]:6.1f} ({planned[k, 1]:5.1f}) F {force[k, 0]:5.2f} "
                f"{force[k, 1]:5.2f}  " + " ".join(f"{names[j]} {err[j]:+5.1f}" for j in worst)
            )
    a, b = plans
    t = a.t - a.t[0]
    diff = np.degrees(b.q[:, 7:] - a.q[:, 7:])
    print(f"plans, {args.stacks[1]} - {args.stacks[0]} (deg):")
    for k in np.flatnonzero((t >= args.start) & (t <= args.end))[:: args.every]:
        worst = np.argsort(-np.abs(diff[k]))[:4]
        print(f"  t {t[k]:5.2f} " + " ".join(f"{names[j]} {diff[k, j]:+5.2f}" for j in worst))


if __name__ == "__main__":
    main()
