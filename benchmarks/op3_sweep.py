"""The OP3 on randomised plants, closed loop, one line per plant: walked to the end, stopped
safely (e.g. the IMU calibration refused to start) or fell, with the torso deviation and the
travelled / planned distance of those that walked.

``wbc bench --physics --robustness N`` counts a plant "up" when it walked to the end (a run
the deployment stopped is listed under ``stopped``, a fall under ``falls``); this sweep prints
each plant's outcome with its figures. Same plants (:func:`wbc.bench.variation.models`, model
k depends only on the seed and k), same closed loop as the benchmark's (the robot's stack,
its defaults: IMU + encoders, step adjustment, the feed-forward at the measured best gain).
benchmarks/op3.md section 8.

    nice -n 5 python benchmarks/op3_sweep.py --models 50 --seed 1 --walk walk10

``--gains JSON`` sets :class:`~wbc.balance.stabilizer.Gains` keywords over the closed loop's
default for the run's feed-forward (:func:`~wbc.balance.stabilizer.default_gains`), e.g. the
no-feed-forward default's previous gains beside the current ones.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np
from _args import json_setting

from wbc import load_robot
from wbc.balance import best_compensate
from wbc.balance.stabilizer import Gains, default_gains
from wbc.balance.stepping import SteppingParams
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import ClosedLoopSpec, play_closed_loop
from wbc.bench.physics import physics_entry
from wbc.bench.runner import run_entry
from wbc.bench.sim_record import physics_record
from wbc.bench.variation import models


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", default="op3")
    p.add_argument("--solver", default="hqp-daqp")
    p.add_argument("--walk", default="walk10")
    p.add_argument("--models", type=int, default=50)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--plants", type=int, nargs="*", help="only these plants of the sweep")
    p.add_argument("--compensate", type=float, default=None, help="default: the measured best")
    p.add_argument("--nominal", action="store_true", help="the nominal plant first")
    p.add_argument("--json", help="write one record per plant")
    p.add_argument(
        "--gains",
        type=json_setting(Gains),
        default=None,
        help="JSON of Gains keywords over the default for the feed-forward, e.g. "
        "'{\"k_dcm_i\": 0}' (default: the closed loop's default gains)",
    )
    a = p.parse_args()
    robot = load_robot(a.robot)
    comp = best_compensate(robot) if a.compensate is None else a.compensate
    entry = physics_entry(a.solver, robot)
    ref = traj.build(a.walk, robot)
    _, rec = run_entry(entry, robot, ref, "tick")
    gains = None if a.gains is None else replace(default_gains(comp), **a.gains)
    spec = ClosedLoopSpec(entry.make, ref, gains, True, True, SteppingParams())  # None: default
    plants = models(robot, a.models, a.seed)
    todo = ([(None, None)] if a.nominal else []) + [
        (k, plants[k]) for k in (a.plants if a.plants else range(a.models))
    ]
    print(f"{robot.name} {a.walk} {entry.name} closed loop, feed-forward x{comp:g}, "
          f"seed {a.seed}, gains {json.dumps(a.gains or {})} over the default")  # fmt: skip
    out = []
    for k, v in todo:
        started = time.perf_counter()
        result, _ = play_closed_loop(spec, robot, v, compensate=comp)
        r = physics_record(rec, result, robot, ref)
        done = bool(result.deploy.completed)
        outcome = "fell" if r["fell"] else ("walked" if done else "stopped")
        row = {"plant": "nominal" if k is None else k, "outcome": outcome,
               "dev_deg": r["orientation_dev_max_deg"], "dist": r.get("distance_ratio"),
               "fall_s": r.get("fall_time_s"), "fall_joint": r.get("fall_joint"),
               "trip": None if result.deploy.trip is None else str(result.deploy.trip),
               **({} if v is None else v.summary)}  # fmt: skip
        out.append(row)
        dist = "-" if row["dist"] is None else f"{row['dist']:.2f}"
        why = row["fall_joint"] if outcome == "fell" else (row["trip"] or "")
        stiff = "" if v is None else f"stiffness x{v.summary['stiffness']:.2f}"
        wall = time.perf_counter() - started
        print(f"{row['plant']:>7} {outcome:>7} dev {row['dev_deg']:5.1f} dist {dist:>5} "
              f"{stiff} {why[:90]} ({wall:.0f} s)", flush=True)  # fmt: skip
    rand = [r for r in out if r["plant"] != "nominal"]
    walked = [r for r in rand if r["outcome"] == "walked"]
    dev = np.array([r["dev_deg"] for r in walked])
    dist = np.array([r["dist"] for r in walked], dtype=float)
    print(f"walked {len(walked)}/{len(rand)}, fell {sum(r['outcome'] == 'fell' for r in rand)}, "
          f"stopped {sum(r['outcome'] == 'stopped' for r in rand)}")  # fmt: skip
    if len(walked):
        within = int(((dist >= 0.9) & (dist <= 1.1)).sum())
        print(f"walked: deviation median {np.median(dev):.2f}, max {dev.max():.2f} deg, "
              f"<= 3 deg: {int((dev <= 3).sum())}; distance {np.nanmin(dist):.2f}-"
              f"{np.nanmax(dist):.2f}, within 0.9-1.1: {within}")  # fmt: skip
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1, default=float)


if __name__ == "__main__":
    main()
