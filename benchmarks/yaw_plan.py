"""The planned motion's vertical angular momentum along a driven walk: per tick, the locked
body's yaw rate the walker's commanded step makes (``J Δq / dt`` with ``J`` the row of
:class:`wbc.tasks.YawMomentumTask`, ``A_z / I_zz``), and its deviation from the reference
torso's yaw rate (what a ``follow`` task asks it to be); a random command sequence on a
randomised model, as ``benchmarks/drive.py --random``::

    nice -n 10 python benchmarks/yaw_plan.py --sequence 4 --model 0 [--yaw-momentum 0.3]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))

import drive

from wbc import Kinematics, load_robot
from wbc.bench.variation import models
from wbc.drive.commands import random_commands
from wbc.drive.envelope import planning_envelope
from wbc.tasks import YawMomentumTask
from wbc.walking.controller import StackController


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequence", type=int, default=4)
    ap.add_argument("--model", type=int, default=0)
    ap.add_argument("--duration", type=float, default=12.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--yaw-momentum", type=float, default=None, metavar="W",
                    help="a follow yaw-momentum task at weight W (default: none)")  # fmt: skip
    args = ap.parse_args(argv)
    robot = load_robot("bioloid")
    row = YawMomentumTask(robot)
    rates: list[float] = []
    yaws: list[float] = []
    dts: list[float] = []
    track = StackController.track

    def spy(self, q, targets, dt, phase_changed):
        q1 = track(self, q, targets, dt, phase_changed)
        J = row.compute(Kinematics(robot, q))[0][0]
        rates.append(float(J @ pin.difference(robot.model, q, q1)) / dt)
        yaws.append(targets.torso_yaw)
        dts.append(dt)
        return q1

    StackController.track = spy  # type: ignore[method-assign]
    limits, window = planning_envelope(robot)
    share = (limits.vx_forward, limits.vx_backward, limits.vy, limits.wz)
    variation = models(robot, args.model + 1, args.seed)[args.model]
    cmds = random_commands(np.random.default_rng([args.seed, 1000 + args.sequence]), share,
                           args.duration)  # fmt: skip
    kw = {} if args.yaw_momentum is None else {"yaw_momentum": args.yaw_momentum,
                                               "yaw_momentum_step": True}  # fmt: skip
    r = drive.run_one(robot, "hqp-daqp", cmds, variation, limits=limits, window=window, **kw)
    a = np.degrees(np.array(rates))
    ref = np.degrees(np.diff(np.unwrap(yaws))) / np.array(dts[1:])
    dev = a[1:] - ref
    print(f"sequence {args.sequence} model {args.model} yaw_momentum {args.yaw_momentum}: fell "
          f"{r['fell']}; the planned locked body's yaw rate rms {np.sqrt((a**2).mean()):.1f} "
          f"deg/s; less the reference torso's: rms {np.sqrt((dev**2).mean()):.1f}, p99 "
          f"{np.percentile(np.abs(dev), 99):.1f} deg/s; {len(a)} ticks")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
