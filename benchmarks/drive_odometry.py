"""Where a driven walk's displacement goes: per random command sequence and randomised model
(as ``benchmarks/drive.py --random``), the commanded displacement, the engine's planned
walking frame, the planned frame plus the leg odometry's landing offsets
(``WalkEngine.odometry_offset``) and the simulated base's, all in the start frame; and the
mean landing error. benchmarks/drive.md (the random sequences) quotes it::

    nice -n 5 python benchmarks/drive_odometry.py --sequences 0 4 --models 5 1
"""

from __future__ import annotations

import argparse
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
from wbc.walking.geometry import rot2


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, nargs="+", default=[0])
    ap.add_argument("--models", type=int, nargs="+", default=[0])
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    robot = load_robot("bioloid")
    limits, window = planning_envelope(robot)
    share = (limits.vx_forward, limits.vx_backward, limits.vy, limits.wz)
    variations = models(robot, max(args.models) + 1, args.seed)
    walkers: list = []
    base = drive_sim_module.Walker

    class Recorded(base):  # the run's walker, kept for its engine
        def __init__(self, *a, **k) -> None:
            super().__init__(*a, **k)
            walkers.append(self)
            self.start_frame = self.engine._centre.copy()

    drive_sim_module.Walker = Recorded
    for i in args.sequences:
        cmds = random_commands(np.random.default_rng([args.seed, 1000 + i]), share,
                               args.duration)  # fmt: skip
        for m in args.models:
            walkers.clear()
            r = drive.run_one(robot, "hqp-daqp", cmds, variations[m], limits=limits,
                              window=window)  # fmt: skip
            e = walkers[0].engine
            c0 = walkers[0].start_frame
            R = rot2(c0[2]).T
            plan = R @ (e._centre[:2] - c0[:2])
            odo = plan + R @ e.odometry_offset
            print(f"sequence {i} model {m}: fell {r['fell']} commanded "
                  f"{np.round(r['commanded_xy_m'], 3)} planned {np.round(plan, 3)} planned + "
                  f"odometry {np.round(odo, 3)} base {np.round(r['travelled_xy_m'], 3)} m; "
                  f"error {100 * r['xy_error_m']:.1f} cm; mean landing error "
                  f"{1000 * np.mean(e.landing_errors):.1f} mm over {r['steps']} steps",
                  flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
