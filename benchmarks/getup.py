"""Getting-up benchmark: the simulated robot dropped on its front or back, left to settle with
its torque off (the state a safe fall leaves), then :func:`wbc.balance.getup_play.get_up`,
closed loop, on ``--models`` randomised models (:func:`wbc.bench.variation.models`, seeded;
model 0 is the first randomised one, ``--nominal`` adds the nominal model) and a random
heading on the floor. Success: the torso upright within 10°, both soles flat, the CoM above
the feet, still so 2 s later (:func:`wbc.drive.sim.judge`). Prints the success rate
and the duration (from the first goal to the end of the rise) per side.

    nice -n 5 python benchmarks/getup.py --models 20 --sides prone supine --nominal
    nice -n 5 python benchmarks/getup.py --models 20 --sides prone --nominal --open-loop

Figures and the exact commands they came from: benchmarks/getup.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("WBC_WAIT_FOR_COMPILE", "1")

from wbc import load_robot
from wbc.bench.variation import models
from wbc.drive.getup_sim import getup_sim


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="bioloid")
    ap.add_argument("--models", type=int, default=20)
    ap.add_argument("--seed", type=int, default=33)
    ap.add_argument("--sides", nargs="+", default=["prone", "supine"])
    ap.add_argument("--nominal", action="store_true", help="also the nominal model")
    ap.add_argument(
        "--open-loop", action="store_true", help="each phase planned from the plan's own end"
    )
    ap.add_argument(
        "--compensate", type=float, default=1.0, help="compliance feed-forward gain (0: off)"
    )
    ap.add_argument(
        "--no-stiffen", action="store_true", help="every phase at the configured servo stiffness"
    )
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    robot = load_robot(args.robot)
    variations = ([None] if args.nominal else []) + models(robot, args.models, args.seed)
    rng = np.random.default_rng(args.seed)
    yaws = rng.uniform(-math.pi, math.pi, len(variations))
    records = []
    start = time.perf_counter()
    for side in args.sides:
        ok, durations = 0, []
        for k, (v, yaw) in enumerate(zip(variations, yaws, strict=True)):
            rec = getup_sim(
                robot,
                side,
                v,
                yaw=float(yaw),
                replan=not args.open_loop,
                compensate=args.compensate,
                stiffen=not args.no_stiffen,
            )
            rec.update(model="nominal" if v is None else k - int(args.nominal), yaw=float(yaw))
            records.append(rec)
            ok += rec["success"]
            if rec["success"]:
                durations.append(rec["duration_s"])
            print(f"{side} model {rec['model']}: {'UP' if rec['success'] else 'FAILED'} "
                  f"({rec['reason']}), {rec['duration_s'] or 0:.1f} s", flush=True)  # fmt: skip
        d = f", {np.median(durations):.1f} s median" if durations else ""
        print(f"{side}: {ok}/{len(variations)} up{d}", flush=True)
        # the torso's elevation at the start of each phase (deg above the horizontal; 90 up)
        side_recs = [r for r in records if r["side"] == side]
        for name in side_recs[0]["phases"] if side_recs else []:
            v = [r["trunk_deg"][name] for r in side_recs if name in r.get("trunk_deg", {})]
            print(f"  trunk at '{name}': median {np.median(v):.0f} deg, "
                  f"{min(v):.0f}..{max(v):.0f} ({len(v)} runs)")  # fmt: skip
    print(f"{len(records)} runs in {time.perf_counter() - start:.0f} s")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(records, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
