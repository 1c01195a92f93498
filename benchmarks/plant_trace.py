"""One randomised plant traced (issue 30): why does it fall, second by second?

The closed loop as ``plant_sweep.py`` runs it (wqp-daqp, step adjustment, the default gains
for the feed-forward with ``--gains`` on top) on plant K of seed S
(:func:`wbc.bench.variation.models`; K -1: the nominal plant). A probe observes
:meth:`wbc.balance.stabilizer.Stabilizer.adjust` (as ``push_trace.py`` does) and the
simulation's log. Per second of the walk: the gyro's yaw rate RMS (rad/s, world vertical)
and its dominant frequency, its ringing as ``Gains.yaw_ring`` measures it (above 3 Hz, the
largest of the second), the RMS of the horizontal rates, the largest heading / tilt error
and torso command (deg), the servos' lag behind their goals as the loop measures it (ms, the
second's median: :func:`wbc.balance.servo_lag.servo_lag`) and the walk's clock rate (the
second's lowest: ``Gains.lag_clock``), the soles' largest heading error (the simulator's
soles against the plan's: issue 30, the footsteps' heading, ``Gains.step_yaw``); then per
stance leg (single support from the soles' floor forces) the knee's load (peak torque / the
plant's stall torque: median, p90, max) and sag (present − goal, deg).

    nice -n 5 python benchmarks/plant_trace.py --walk lateral_wb --seed 1 --plant 47
    nice -n 5 python benchmarks/plant_trace.py --walk walk10_wb --seed 1 --plant 42 \\
        --gains '{"yaw_cutoff": 2}'
"""

from __future__ import annotations

import argparse
import json

import _args
import numpy as np
from plant_sweep import plant_run

from wbc.balance import stabilizer as stab_mod
from wbc.compiled.rows import log3


def trace(walk: str, seed: int, plant: int, gains: dict, compensate: float) -> None:
    """Run plant ``plant`` of ``seed`` on ``walk`` and print its trace (module docstring)."""
    run = plant_run(walk, seed, plant, gains, compensate)
    robot, v = run.robot, run.plant
    clock, rows, soles = [0.0], [], [0.0]
    original = stab_mod.Stabilizer.adjust

    def observed(self, targets, com_vel_ref, q_cmd, dt):
        self.measure_lag = True  # (measured only when read)
        out = original(self, targets, com_vel_ref, q_cmd, dt)
        if self.last is not None:  # (not while calibrating)
            cmd = np.empty(3)  # the torso command: log(R_cmd R_refᵀ)
            log3(np.ascontiguousarray(out.torso_rotation @ targets.torso_rotation.T), cmd)
            w = self.last.rotation @ self.last.angular_velocity  # world frame
            rows.append((clock[0], *self.error, *w, *cmd, self.servo_lag, self.clock, soles[0]))
            soles.append(targets)  # (the plan's soles: compared in the next simulator tick)
        return out

    def tick(sim) -> None:
        clock[0] = sim.time
        if len(soles) > 1:  # the soles' largest heading error, the simulator's against the plan
            t = soles.pop()
            soles[0] = max(abs(wrap(yaw(sim.site_pose(f).rotation) - yaw(t.sole(f).rotation)))
                           for f in ("l_sole", "r_sole"))  # fmt: skip

    stab_mod.Stabilizer.adjust = observed
    try:
        res, r = run.play(on_tick=tick)
    finally:
        stab_mod.Stabilizer.adjust = original
    summary = json.dumps(v.summary if v else {}, default=float)
    print(f"{walk}, seed {seed}, plant {plant}: {summary}")
    if r["fell"]:
        outcome = f"fell at {r['fall_time_s']:.2f} s, {r['fall_joint']}"
    else:
        outcome = f"up, {r['orientation_dev_max_deg']:.1f}°, travelled {r['distance_ratio']:.2f}"
    print(f"gains {json.dumps(gains)}, feed-forward {compensate}: {outcome}")
    a = np.array(rows)
    ts = a[:, 0] - res.playback_start
    e, w, cmd, lag = np.degrees(a[:, 1:4]), a[:, 4:7], np.degrees(a[:, 7:10]), 1e3 * a[:, 10]
    ring = ringing(ts, w[:, 2])
    print(
        "| s | yaw rate RMS | its frequency | ringing (> 3 Hz) | tilt rate RMS | heading err° "
        "| tilt err° | heading cmd° | tilt cmd° | servo lag ms | clock | soles' heading err° |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for s in range(int(np.ceil(ts.max())) if len(ts) else 0):
        m = (ts >= s) & (ts < s + 1)
        if m.sum() < 8:
            continue
        wz = w[m, 2] - w[m, 2].mean()
        spectrum = np.abs(np.fft.rfft(wz))
        f = np.fft.rfftfreq(len(wz), float(np.median(np.diff(ts[m]))))
        print(f"| {s}–{s + 1} | {np.sqrt(np.mean(w[m, 2] ** 2)):.2f} "
              f"| {f[1 + np.argmax(spectrum[1:])]:.1f} Hz | {ring[m].max():.2f} "
              f"| {np.sqrt(np.mean(w[m, :2] ** 2)):.2f} | {np.abs(e[m, 2]).max():.1f} "
              f"| {np.hypot(e[m, 0], e[m, 1]).max():.1f} | {np.abs(cmd[m, 2]).max():.1f} "
              f"| {np.hypot(cmd[m, 0], cmd[m, 1]).max():.1f} "
              f"| {np.median(lag[m]):.1f} | {a[m, 11].min():.2f} "
              f"| {np.degrees(a[m, 12].max()):.1f} |")  # fmt: skip
    log, names = res.log, list(robot.joint_names)
    t, q, goal, peak, force = (log[k] for k in ("t", "q", "goal", "peak_torque", "sole_force"))
    t = t - res.playback_start
    stall = np.broadcast_to(np.asarray(res.sim.servo_params.stall_torque), peak.shape[1:])
    end = r["fall_time_s"] if r["fell"] else np.inf
    total = force.sum(axis=1)
    for leg, side in (("l", 0), ("r", 1)):
        j = next((k for k, n in enumerate(names) if n.startswith(leg) and "knee" in n), None)
        m = (t > 0) & (t < end) & (force[:, side] > 0.9 * total) & (total > 0)
        if j is None or not m.any():
            continue
        load = peak[m, j] / stall[j]
        sag = np.degrees(q[m, 7 + j] - goal[m, j])
        print(f"{names[j]} in its single support ({m.sum()} ticks): load median "
              f"{np.median(load):.2f}, p90 {np.percentile(load, 90):.2f}, max {load.max():.2f}; "
              f"sag median {np.median(sag):.1f}°, max {sag.max():.1f}°")  # fmt: skip


def yaw(R: np.ndarray) -> float:
    """The heading of a rotation (its x axis's)."""
    return float(np.arctan2(R[1, 0], R[0, 0]))


def wrap(a: float) -> float:
    """``a`` wrapped to (−π, π]."""
    return float((a + np.pi) % (2 * np.pi) - np.pi)


def ringing(t: np.ndarray, wz: np.ndarray) -> np.ndarray:
    """The yaw loop's ringing as ``Gains.yaw_ring`` measures it, per tick (rad/s): the
    vertical rate high-passed at :data:`~wbc.balance.stabilizer.RING_HZ`, the RMS of the
    rest over :data:`~wbc.balance.stabilizer.RING_WINDOW` (exponential)."""
    low, mean_square, out = 0.0, 0.0, np.zeros(len(wz))
    dts = np.diff(t, prepend=t[0] - float(np.median(np.diff(t))) if len(t) > 1 else 0.01)
    for i, (dt, x) in enumerate(zip(dts, wz, strict=True)):
        u = x - low
        low += (1.0 - np.exp(-2.0 * np.pi * stab_mod.RING_HZ * dt)) * u
        mean_square += (1.0 - np.exp(-dt / stab_mod.RING_WINDOW)) * (u * u - mean_square)
        out[i] = np.sqrt(mean_square)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    _args.plant(p, walk="lateral_wb", seed=1, plant=47, nominal=True)
    p.add_argument("--compensate", type=float, default=0.0, help="the feed-forward's gain")
    args = p.parse_args()
    trace(args.walk, args.seed, args.plant, args.gains, args.compensate)


if __name__ == "__main__":
    main()
