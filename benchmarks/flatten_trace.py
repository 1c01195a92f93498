"""The soles' relative tilt by the encoders through each walking double support of one random
command sequence on one randomised model (as ``benchmarks/drive.py --random``), with and
without ``Walker(flatten=RATE)`` (wbc.drive.flatten): per double support its tilt at the
touch-down, its largest and at the lift-off (°), and how many lift-offs leave the soles more
than ``--above`` degrees apart; the run's displacement error::

    nice -n 10 python benchmarks/flatten_trace.py --sequence 4 --model 0 --flatten 10
    nice -n 10 python benchmarks/flatten_trace.py --sequence 4 --model 0           # off
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import drive

import wbc.drive.sim as drive_sim_module
from wbc import load_robot
from wbc.bench.variation import models
from wbc.drive.commands import random_commands
from wbc.drive.envelope import planning_envelope
from wbc.drive.liftoff import soles_tilt
from wbc.types import SUPPORT_DOUBLE


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sequence", type=int, required=True)
    ap.add_argument("--model", type=int, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--flatten", type=float, default=None, metavar="RATE")
    ap.add_argument("--above", type=float, default=4.0, metavar="DEG")
    args = ap.parse_args(argv)
    robot = load_robot("bioloid")
    limits, window = planning_envelope(robot)
    share = (limits.vx_forward, limits.vx_backward, limits.vy, limits.wz)
    variation = models(robot, args.model + 1, args.seed)[args.model]
    supports: list[list[float]] = []  # per walking double support after a landing: tilts (°)
    base = drive_sim_module.Walker

    class Traced(base):  # type: ignore[misc, valid-type]
        def tick(self, dt=None):
            q = super().tick(dt)
            e, present = self.last, self._present_configuration()
            double = e is not None and e.support == SUPPORT_DOUBLE and self.engine.walking
            if double and present is not None and self.engine.steps_taken > 0:
                tilt = math.degrees(soles_tilt(self.robot, present))
                if self._new_support:
                    supports.append([])
                supports[-1].append(tilt)
            self._new_support = not double
            return q

        _new_support = True

    drive_sim_module.Walker = Traced
    try:
        cmds = random_commands(np.random.default_rng([args.seed, 1000 + args.sequence]), share,
                               args.duration)  # fmt: skip
        r = drive.run_one(robot, "hqp-daqp", cmds, variation, limits=limits, window=window,
                          flatten=args.flatten)  # fmt: skip
    finally:
        drive_sim_module.Walker = base
    last = [s[-1] for s in supports if s]
    above = [i for i, s in enumerate(supports) if s and s[-1] > args.above]
    yaw = math.degrees(r["yaw_error_rad"])
    print(f"sequence {args.sequence} model {args.model} flatten {args.flatten}: "
          f"fell {r['fell']}, error {1000 * r['xy_error_m']:.1f} mm, {yaw:.1f}°")  # fmt: skip
    print(f"{len(supports)} double supports; at the lift-off the soles' tilt mean "
          f"{np.mean(last):.2f}°, > {args.above}°: {len(above)}, "
          f"largest {max(last):.1f}°")  # fmt: skip
    for i in above:
        s = supports[i]
        print(f"  #{i}: touch-down {s[0]:.1f}°, largest {max(s):.1f}°, lift-off {s[-1]:.1f}°")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
