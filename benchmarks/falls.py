"""Fall detection and the safe fall, in the simulator: pushes beyond recovery, with and without.

A ``walk`` is walked closed loop (wqp-daqp) on the nominal simulated robot and pushed at
mid first single support (10 ms on the torso) well beyond its bound in each direction
(``--impulse`` N·s). With the detector (:mod:`wbc.balance.fall`) and without, per run: the
detection delay after the push ends (ms), the peak servo torque from 50 ms after the
detection to the end (/ stall; the run without the detector over the same window), the RMS
servo torque over that window, the torso's largest speed in the last 50 mm above its
lowest point (m/s: the impact speed), and the largest goal excursion beyond a joint limit
(deg, before the deployment's clamp).

    nice -n 5 python benchmarks/falls.py --walk walk10_wb --impulse 2.5
"""

from __future__ import annotations

import argparse

import numpy as np

from wbc import load_robot
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import ClosedLoopSpec, closed_loop_figures, play_closed_loop
from wbc.bench.pushes import PUSH_DURATION, push_direction
from wbc.bench.runner import run_entry
from wbc.bench.sim_record import mid_single_support
from wbc.bench.solvers import registry


def impact_speed(t: np.ndarray, base: np.ndarray, window: float = 0.05) -> float:
    """The torso's largest speed (m/s) while within ``window`` m above its lowest height."""
    v = np.linalg.norm(np.gradient(base, t, axis=0), axis=1)
    low = base[:, 2] <= base[:, 2].min() + window
    return float(v[low].max())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--solver", default="wqp-daqp")
    p.add_argument("--walk", default="walk10_wb")
    p.add_argument("--impulse", type=float, default=2.5)
    p.add_argument("--directions", nargs="+", default=["forward", "backward", "toward", "away"])
    args = p.parse_args()
    robot = load_robot("bioloid")
    entry = registry()[args.solver]
    ref = traj.build(args.walk, robot)
    _, rec = run_entry(entry, robot, ref, "tick")
    t_push = mid_single_support(rec)
    print(f"{args.solver} on {args.walk}, {args.impulse} N·s at {t_push:.2f} s")
    print("| push | detector | detected after the push (ms) | why | peak τ/τs | RMS τ/τs | "
          "impact m/s | goal beyond a limit ° | stop |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for d in args.directions:
        u = push_direction(rec, d)
        push = (t_push, u * args.impulse / PUSH_DURATION, PUSH_DURATION)
        window = None
        for on in (True, False):
            spec = ClosedLoopSpec(entry.make, ref)
            if not on:
                spec = ClosedLoopSpec(entry.make, ref, fall=None)
            result, loop = play_closed_loop(spec, robot, push=push, settle=1.5)
            log = result.log
            t = log["t"] - result.playback_start
            after = t >= t_push
            stall = result.sim.servo_params.stall_torque
            fall = loop.stabilizer.fall
            delay = why = "-"
            if fall is not None and fall.time is not None:
                # the detector's clock starts at the walk's first tick: the playback's start
                delay = f"{1e3 * (fall.time - t_push - PUSH_DURATION):.0f}"
                why = fall.reason.split(" (")[0]
                window = fall.time + 0.05
            late = t >= (window if window is not None else t_push)
            peak = float(log["peak_torque"][late].max() / stall)
            rms = float(np.sqrt(np.mean(log["peak_torque"][late] ** 2)) / stall)
            speed = impact_speed(t[after], log["q"][after, :3])
            excess = closed_loop_figures(loop)["goal_limit_excess_deg"]
            stop = result.deploy.stop_action or "-"
            print(f"| {d} | {'on' if on else 'off'} | {delay} | {why} | {peak:.2f} | {rms:.2f} | "
                  f"{speed:.2f} | {excess:.2f} | {stop} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
