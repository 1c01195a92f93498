"""One randomised plant's single supports traced tick by tick (issue 30, eighteenth session).

The closed loop as ``plant_sweep.py`` runs it (wqp-daqp, step adjustment, the lift-off
hold, the no-feed-forward gains with ``--gains`` on top) on plant K of seed S; every
``--every`` s from ``--from`` s: the phase and stance sole of the played reference, the
torso's real roll and pitch in the reference heading's frame (deg), the estimate's tilt
error (deg), the hip strategy's roll (deg), the estimated DCM's offset outward of the
stance sole's centre (mm; positive: toward the side no step reaches) and its error against
the reference along / across the heading (mm), the DCM integral (mm·s), the soles' forces
(N) and, per leg, the hip roll's and knee's goal − present (deg) and peak torque / stall.

    nice -n 5 python benchmarks/support_trace.py --walk turn_wb --seed 2 --plant 8 --from 3.8
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

import _args
import numpy as np

from wbc import load_robot
from wbc.balance import stabilizer as stab_mod
from wbc.balance.retime import HoldParams
from wbc.balance.stabilizer import default_gains
from wbc.balance.stepping import SteppingParams
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import ClosedLoopSpec, play_closed_loop
from wbc.bench.runner import run_entry
from wbc.bench.sim_record import physics_record
from wbc.bench.solvers import select
from wbc.bench.variation import models


def trace(walk: str, seed: int, plant: int, gains: dict, start: float, every: float) -> None:
    """Run plant ``plant`` of ``seed`` on ``walk`` and print its trace (module docstring)."""
    robot = load_robot("bioloid")
    entry = select(["wqp-daqp"], None, "tick")[0][0]
    ref = traj.build(walk, robot)
    _, rec = run_entry(entry, robot, ref, "tick")
    v = models(robot, plant + 1, seed)[plant]
    g = replace(default_gains(0.0), **gains)
    spec = ClosedLoopSpec(entry.make, ref, g, True, True, SteppingParams(), HoldParams())
    clock, rows = [0.0], []
    original = stab_mod.Stabilizer.adjust

    def observed(self, targets, com_vel_ref, q_cmd, dt):
        out = original(self, targets, com_vel_ref, q_cmd, dt)
        if self.last is not None:
            est = self.last
            yaw = float(targets.torso_yaw)
            h = np.array([np.cos(yaw), np.sin(yaw)])  # the heading
            n = np.array([-h[1], h[0]])  # its left
            stance = targets.support if targets.phase == "single" else ""
            out_off = np.nan
            if stance:
                sole = getattr(targets, stance).translation[:2]
                side = 1.0 if stance.startswith("l") else -1.0  # outward: left of a left sole
                out_off = side * float(np.dot(est.dcm[:2] - sole, n))
            xi_ref = targets.com[:2] + com_vel_ref[:2] / self.estimator.omega0
            d = est.dcm[:2] - xi_ref
            rows.append((clock[0], targets.t, stance, out_off, float(d @ h), float(d @ n),
                         *np.degrees(self.error[:2]), *np.degrees(self.hip),
                         *(1e3 * self.dcm_integral), yaw))  # fmt: skip
        return out

    def tick(sim) -> None:
        clock[0] = sim.time

    stab_mod.Stabilizer.adjust = observed
    try:
        res, loop = play_closed_loop(spec, robot, v, on_tick=tick)
    finally:
        stab_mod.Stabilizer.adjust = original
    r = physics_record(rec, res, robot, ref)
    print(f"{walk}, seed {seed}, plant {plant}, gains {json.dumps(gains)}, identified "
          f"{loop.stiffness_scale}: "
          + (f"fell at {r['fall_time_s']:.2f} s, {r['fall_joint']}" if r["fell"]
             else f"up, {r['orientation_dev_max_deg']:.1f}°"))  # fmt: skip
    print(json.dumps(v.summary, default=float))
    log, names = res.log, list(robot.joint_names)
    t = np.asarray(log["t"]) - res.playback_start
    q, goal, force = np.asarray(log["q"]), np.asarray(log["goal"]), np.asarray(log["sole_force"])
    peak = np.asarray(log["peak_torque"])
    frac = peak / np.broadcast_to(np.asarray(res.sim.servo_params.stall_torque), peak.shape[1:])
    a = np.array([row[:2] + row[3:] for row in rows], dtype=float)
    stances = [row[2] for row in rows]
    ta = a[:, 0] - res.playback_start
    watch = [k for k, nm in enumerate(names) if "hip_roll" in nm or "knee" in nm]
    print(
        "| s | ref t | stance | roll° | pitch° | err r/p° | hip° | DCM out mm | DCM err "
        "along/left mm | ∫ mm·s | l/r N | " + " | ".join(names[k] for k in watch) + " |"
    )
    print("|---" * (12 + len(watch)) + "|")
    for tt in np.arange(start, t[-1], every):
        i = int(np.searchsorted(t, tt))
        j = min(int(np.searchsorted(ta, tt)), len(ta) - 1)
        x, y, z, w = q[i, 3:7]
        R = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        yaw = a[j, 11]
        up = R[:, 2]  # the torso's up axis: roll (+ left side up), pitch (+ forward)
        along = np.cos(yaw) * up[0] + np.sin(yaw) * up[1]
        left = -np.sin(yaw) * up[0] + np.cos(yaw) * up[1]
        roll, pitch = (
            np.degrees(np.arcsin(np.clip(-left, -1, 1))),
            np.degrees(np.arcsin(np.clip(along, -1, 1))),
        )
        f = frac[max(i - 2, 0) : i + 3].max(axis=0)
        cols = " | ".join(f"{np.degrees(goal[i, k] - q[i, 7 + k]):+.1f} {f[k]:.2f}"
                          for k in watch)  # fmt: skip
        print(f"| {tt:.2f} | {a[j, 1]:.2f} | {stances[j] or '-'} | {roll:+.1f} | {pitch:+.1f} "
              f"| {a[j, 5]:+.1f} {a[j, 6]:+.1f} | {np.hypot(a[j, 7], a[j, 8]):.1f} "
              f"| {a[j, 2] * 1e3:+.0f} | {a[j, 3] * 1e3:+.0f} {a[j, 4] * 1e3:+.0f} "
              f"| {a[j, 9]:+.1f} {a[j, 10]:+.1f} | {force[i][0]:.0f} {force[i][1]:.0f} "
              f"| {cols} |")  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    _args.plant(p, walk="turn_wb", seed=2, plant=8)
    _args.rows(p, start=3.6, every=0.04)
    args = p.parse_args()
    trace(args.walk, args.seed, args.plant, args.gains, args.start, args.every)


if __name__ == "__main__":
    main()
