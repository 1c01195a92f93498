"""A stiff, late plant's fall traced tick by tick (issue 30, nineteenth session).

The closed loop as ``plant_sweep.py`` runs it (:func:`plant_sweep.plant_run`: wqp-daqp, step
adjustment, the lift-off hold, the no-feed-forward gains with ``--gains`` on top) on plant K
of seed S; every ``--every`` s from ``--from`` s: the played reference's phase, the torso's
estimated tilt error (roll, pitch about the reference heading; heading error; deg), the
torso command's tilt and heading parts (deg: what the feedback asks of the legs), the gyro's
horizontal and vertical rates (rad/s), the hip strategy's roll (deg), the servos' measured lag
(ms, :func:`wbc.balance.servo_lag.servo_lag`), the soles' heading error (the simulator's soles
against the plan's, deg) and the stance sole's spin (its heading error's rate over the last 10
simulator ticks, deg/s; twenty-first session), and for the joints named by ``--joints``
(substrings) goal − present (deg) and peak torque / stall.

    nice -n 5 python benchmarks/late_trace.py --walk lateral_wb --seed 0 --plant 18 \\
        --joints hip_yaw hip_pitch --from 2.4
"""

from __future__ import annotations

import argparse
import json

import _args
import numpy as np
from plant_sweep import plant_run
from plant_trace import wrap
from plant_trace import yaw as heading

from wbc.balance import stabilizer as stab_mod
from wbc.compiled.rows import log3


def trace(walk: str, seed: int, plant: int, gains: dict, joints: list[str], start: float,
          every: float) -> None:  # fmt: skip
    """Run plant ``plant`` of ``seed`` on ``walk`` and print its trace (module docstring)."""
    run = plant_run(walk, seed, plant, gains)
    robot, v = run.robot, run.plant
    clock, rows, soles, plan = [0.0], [], {}, [None]
    original = stab_mod.Stabilizer.adjust

    def observed(self, targets, com_vel_ref, q_cmd, dt):
        self.measure_lag = True  # (measured only when read)
        out = original(self, targets, com_vel_ref, q_cmd, dt)
        if self.last is not None:  # (not while calibrating)
            cmd = np.empty(3)  # the torso command: log(R_cmd R_refᵀ), world
            log3(np.ascontiguousarray(out.torso_rotation @ targets.torso_rotation.T), cmd)
            yaw = float(targets.torso_yaw)
            h = np.array([np.cos(yaw), np.sin(yaw), 0.0])
            n = np.array([-h[1], h[0], 0.0])
            w = self.last.rotation @ self.last.angular_velocity
            e = self.error
            stance = targets.support if targets.phase == "single" else "-"
            rows.append((clock[0], float(targets.t), stance, e @ h, e @ n, e[2], cmd @ h,
                         cmd @ n, cmd[2], np.hypot(w[0], w[1]), w[2],
                         float(np.hypot(*self.hip)), self.servo_lag,
                         float(getattr(self, "stiffness_scale", None) or 0.0), yaw))  # fmt: skip
            plan[0] = targets  # (the soles' plan: compared in the next simulator tick)
        return out

    def tick(sim) -> None:
        clock[0] = sim.time
        if plan[0] is not None:  # the soles' heading, the simulator's against the plan (deg)
            soles[round(sim.time, 4)] = [
                np.degrees(wrap(heading(sim.site_pose(f).rotation)
                                - heading(plan[0].sole(f).rotation)))
                for f in ("l_sole", "r_sole")]  # fmt: skip

    stab_mod.Stabilizer.adjust = observed
    try:
        res, r = run.play(on_tick=tick)
    finally:
        stab_mod.Stabilizer.adjust = original
    print(f"{walk}, seed {seed}, plant {plant}, gains {json.dumps(gains)}: "
          + (f"fell at {r['fall_time_s']:.2f} s, {r['fall_joint']}" if r["fell"]
             else f"up, {r['orientation_dev_max_deg']:.1f}°, travelled "
                  f"{r['distance_ratio']:.2f}"))  # fmt: skip
    print(json.dumps(v.summary if v else {}, default=float), "identified", rows[-1][13])
    log, names = res.log, list(robot.joint_names)
    t = np.asarray(log["t"]) - res.playback_start
    q, goal, peak = np.asarray(log["q"]), np.asarray(log["goal"]), np.asarray(log["peak_torque"])
    frac = peak / np.broadcast_to(np.asarray(res.sim.servo_params.stall_torque), peak.shape[1:])
    ta = np.array([row[0] for row in rows]) - res.playback_start
    watch = [k for k, nm in enumerate(names) if any(s in nm for s in joints)]
    print("| s | ref t | stance | true roll/pitch° | err roll/pitch/yaw° | cmd roll/pitch/yaw° "
          "| gyro xy/z rad/s | hip° | lag ms | soles' heading err l/r° | stance spin °/s | "
          + " | ".join(names[k] for k in watch) + " |")  # fmt: skip
    print("|---" * (11 + len(watch)) + "|")
    st = np.array(sorted(soles))
    sy = np.array([soles[k] for k in st])
    for tt in np.arange(start, t[-1], every):
        i = int(np.searchsorted(t, tt))
        j = min(int(np.searchsorted(ta, tt)), len(ta) - 1)
        a = rows[j]
        f = frac[max(i - 2, 0) : i + 3].max(axis=0)
        cols = " | ".join(f"{np.degrees(goal[i, k] - q[i, 7 + k]):+.1f} {f[k]:.2f}"
                          for k in watch)  # fmt: skip
        d = np.degrees(a[3:9])
        x, y, z, w = q[i, 3:7]  # the torso's true up axis (the simulator's): roll, pitch
        up = np.array([2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)])
        yaw = float(np.arctan2(np.sin(a[14]), np.cos(a[14])))
        along = np.cos(yaw) * up[0] + np.sin(yaw) * up[1]
        left = -np.sin(yaw) * up[0] + np.cos(yaw) * up[1]
        true = np.degrees(np.arcsin(np.clip([-left, along], -1, 1)))
        k = min(int(np.searchsorted(st, a[0])), len(st) - 1)
        side = 0 if a[2] == "l_sole" else 1 if a[2] == "r_sole" else None
        spin = (
            "-"
            if side is None or k < 10
            else f"{(sy[k, side] - sy[k - 10, side]) / (st[k] - st[k - 10]):+.0f}"
        )
        print(
            f"| {tt:.2f} | {a[1]:.2f} | {a[2]} | {true[0]:+.1f} {true[1]:+.1f} "
            f"| {d[0]:+.1f} {d[1]:+.1f} {d[2]:+.1f} "
            f"| {d[3]:+.1f} {d[4]:+.1f} {d[5]:+.1f} | {a[9]:.2f} {a[10]:+.2f} "
            f"| {np.degrees(a[11]):.1f} | {a[12] * 1e3:.0f} | {sy[k, 0]:+.1f} {sy[k, 1]:+.1f} "
            f"| {spin} | {cols} |"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    _args.plant(p, walk="lateral_wb", seed=0, plant=18)
    p.add_argument("--joints", nargs="+", default=["hip_yaw", "hip_pitch"])
    _args.rows(p, start=2.0, every=0.04)
    args = p.parse_args()
    trace(args.walk, args.seed, args.plant, args.gains, args.joints, args.start, args.every)


if __name__ == "__main__":
    main()
