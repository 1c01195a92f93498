"""Cost of the balance goal shaping per control tick, as a share of a 100 Hz tick.

python benchmarks/balance_cost.py [--calls 2000]
"""

from __future__ import annotations

import argparse
import timeit

import numpy as np

from wbc.balance.compliance import ComplianceCompensator
from wbc.balance.feedback import GyroFeedback
from wbc.imu import Imu, ImuReading
from wbc.model import load_robot
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT


class _Imu(Imu):
    def read(self) -> ImuReading:
        return ImuReading(0.0, np.array([0, 0, 0, 1.0]), np.array([0.1, 0.2, 0.0]), np.zeros(3))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--calls", type=int, default=2000)
    args = parser.parse_args()
    robot = load_robot()
    comp, gyro = ComplianceCompensator(robot), GyroFeedback(robot, _Imu())
    joints = robot.joints(robot.configuration("walk_ready"))
    tick = 0.01
    cases = {
        "compliance goals, double support": lambda: comp.goals(joints, SUPPORT_DOUBLE),
        "compliance goals, single support": lambda: comp.goals(joints, SUPPORT_LEFT),
        "gyro feedback offsets": lambda: gyro.offsets(joints),
    }
    for name, f in cases.items():
        f()
        t = min(timeit.repeat(f, number=args.calls, repeat=3)) / args.calls
        print(f"{name:<36} {100 * t / tick:5.2f} % of a 10 ms tick")


if __name__ == "__main__":
    main()
