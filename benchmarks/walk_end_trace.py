"""The walk's end of one randomised plant traced (issue 30, seventeenth session).

The closed loop as ``plant_sweep.py`` runs it (wqp-daqp, step adjustment, the lift-off
hold, the no-feed-forward gains with ``--gains`` on top) on plant K of seed S; every 0.1 s
from ``--from`` s: the torso's tilt (deg), each sole's vertical force (N), where the CoM
stands between the soles (0: over the left, 1: over the right) and ahead of the line
between them (mm), the CoP's margin to the contact hull (mm), the knees' and ankle pitches'
peak torque / the plant's stall torque over ±50 ms and the largest of any joint.

    nice -n 5 python benchmarks/walk_end_trace.py --walk turn_wb --seed 0 --plant 45
    nice -n 5 python benchmarks/walk_end_trace.py --walk turn_wb --seed 3 --plant 0 \\
        --gains '{"lift": -0.008}'
"""

from __future__ import annotations

import argparse
import json

import _args
import numpy as np
from plant_sweep import plant_run


def trace(walk: str, seed: int, plant: int, gains: dict, start: float) -> None:
    """Run plant ``plant`` of ``seed`` on ``walk`` and print its end (module docstring)."""
    run = plant_run(walk, seed, plant, gains)
    robot = run.robot
    res, r = run.play()
    print(f"{walk}, seed {seed}, plant {plant}, gains {json.dumps(gains)}: "
          + (f"fell at {r['fall_time_s']:.2f} s, {r['fall_joint']}" if r["fell"]
             else f"up, {r['orientation_dev_max_deg']:.1f}°"))  # fmt: skip
    log, names = res.log, list(robot.joint_names)
    t = np.asarray(log["t"]) - res.playback_start
    q, com, soles = np.asarray(log["q"]), np.asarray(log["com"]), np.asarray(log["soles"])
    force, margin = np.asarray(log["sole_force"]), np.asarray(log["cop_margin"])
    peak = np.asarray(log["peak_torque"])
    frac = peak / np.broadcast_to(np.asarray(res.sim.servo_params.stall_torque), peak.shape[1:])
    watch = [k for k, n in enumerate(names) if "knee" in n or "ankle_pitch" in n]
    print("| s | tilt° | left N | right N | CoM l→r | CoM ahead mm | CoP margin mm | "
          + " | ".join(names[k] for k in watch) + " | largest |")  # fmt: skip
    print("|---" * (8 + len(watch)) + "|")
    for tt in np.arange(start, t[-1], 0.1):
        i = int(np.searchsorted(t, tt))
        x, y, _, _ = q[i, 3:7]
        tilt = np.degrees(np.arccos(np.clip(1 - 2 * (x * x + y * y), -1, 1)))
        left, d = soles[i][0][:2], soles[i][1][:2] - soles[i][0][:2]
        c = com[i][:2] - left
        across = float(np.dot(c, d) / np.dot(d, d))
        ahead = float(d[0] * c[1] - d[1] * c[0]) / float(np.linalg.norm(d))
        f = frac[max(i - 5, 0) : i + 5].max(axis=0)
        j = int(np.argmax(f))
        loads = " | ".join(f"{f[k]:.2f}" for k in watch)
        print(f"| {tt:.1f} | {tilt:.1f} | {force[i][0]:.1f} | {force[i][1]:.1f} | {across:.2f} "
              f"| {ahead * 1e3:.1f} | {margin[i] * 1e3:.1f} | {loads} "
              f"| {names[j]} {f[j]:.2f} |")  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    _args.plant(p, walk="turn_wb", seed=0, plant=45)
    _args.rows(p, start=3.6)
    args = p.parse_args()
    trace(args.walk, args.seed, args.plant, args.gains, args.start)


if __name__ == "__main__":
    main()
