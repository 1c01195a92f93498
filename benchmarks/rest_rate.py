"""The plant's true rate while the drive walker's IMU calibration stands at rest: one
randomised Bioloid (``benchmarks/drive.py``'s models), the calibration lengthened to
``--rest`` s (the targets pass unchanged, so its first 0.3 s are the default's), the simulated
IMU's bias- and noise-free sensor in the torso frame per tick; printed per window: its mean
(what the calibration would take as bias) and the largest rate (deg/s).

    python benchmarks/rest_rate.py --model 0 --rest 3 --window 0.15
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import drive

import wbc.balance.stabilizer as stabilizer
from wbc import load_robot
from wbc.bench.variation import models
from wbc.drive.commands import Command
from wbc.drive.envelope import planning_envelope


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", type=int, default=0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rest", type=float, default=3.0, help="the calibration's rest (s)")
    ap.add_argument("--window", type=float, default=0.15, help="the windows' length (s)")
    args = ap.parse_args(argv)
    rates: list[np.ndarray] = []
    calibrate = stabilizer.Stabilizer._calibrate

    def recorded(self, targets, reading, present, joints, dt):
        imu = self.imu
        while not hasattr(imu, "sim") and hasattr(imu, "imu"):
            imu = imu.imu
        true = np.array(imu.sim.data.sensordata[imu._adr["imu_gyro"]])
        rates.append(self.mount.rotation @ true if self.mount is not None else true)
        return calibrate(self, targets, reading, present, joints, dt)

    stabilizer.Stabilizer._calibrate = recorded
    robot = load_robot("bioloid")
    limits, window = planning_envelope(robot)
    variation = models(robot, args.model + 1, args.seed)[args.model]
    drive.run_one(robot, "hqp-daqp", [Command(0.5, 0.0, 0.0, 0.0)], variation, limits=limits,
                  window=window, yaw_rest=0.0, calibrate=args.rest)  # fmt: skip
    w = np.degrees(np.array(rates))
    n = max(1, round(args.window / 0.01))
    print(f"model {args.model}: the true rate at rest (deg/s; roll, pitch, yaw; torso frame)")
    for k in range(0, len(w) - n + 1, n):
        m, top = w[k : k + n].mean(axis=0), np.abs(w[k : k + n]).max(axis=0)
        span = f"{k / 100:5.2f}-{(k + n) / 100:5.2f} s"
        print(f"{span}  mean {np.round(m, 2)}  largest {np.round(top, 1)}")
    print(f"whole rest: mean {np.round(w.mean(axis=0), 2)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
