"""The closed loop's share of a control tick: state estimator + feedback vs the solve.

Runs ``walk10_wb`` through :class:`wbc.walking.loop.Session` with a
:class:`wbc.balance.stabilizer.Stabilizer` (default gains, the fall detector, a finished
start-up calibration applied to every sample) and the step adjustment's check
(:class:`wbc.balance.stepping.StepAdjuster`: issue 30's default loop) for each family, the
sensors replaced by in-memory ones (present positions = the controller's own joints, a still
IMU at the reference torso orientation: the estimator and the feedback do all their work, no
simulator runs; the noisy positions are stored before each tick, as a deployment's
``last_present`` is). Per tick, ``Session.feedback_time`` (estimator + feedback) and
``Session.solve_time`` (the controller's tick) are timed with the same clock (the step
check's ``Session.stepping_time`` counted with the feedback); printed: the
median over the walk of feedback / (feedback + solve), best of ``--repeats`` runs, and the
medians in µs, against issue 15's target (estimator + feedback ≤ 30 % of a tick). ``w/o
reads``: the same share without the sensor reads (the still IMU's sample, the positions),
which a driver does (``Stabilizer.read_time``).

    python benchmarks/closed_loop_cost.py [--solvers wqp-daqp hqp-daqp placo pink]
"""

from __future__ import annotations

import argparse

import numpy as np

from wbc import load_robot
from wbc.balance.fall import FallDetector, FallParams
from wbc.balance.stabilizer import Stabilizer
from wbc.balance.stepping import StepAdjuster, SteppingParams
from wbc.bench import trajectories as traj
from wbc.bench.solvers import registry
from wbc.imu import GRAVITY, Imu, ImuCalibration, ImuReading
from wbc.walking.loop import Session


class StillImu(Imu):
    def __init__(self, R: np.ndarray) -> None:
        import pinocchio as pin

        self.quat = pin.Quaternion(R).coeffs()
        self.acc = R.T @ np.array([0.0, 0.0, GRAVITY])
        self.still = np.zeros(3)

    def read(self) -> ImuReading:  # (a new, validated sample each tick, as a driver gives)
        return ImuReading(0.0, self.quat, self.still, self.acc)


def measure(solver: str, robot, ref) -> tuple[float, float, float, float]:
    rng = np.random.default_rng(0)
    noise = np.radians(0.29) * rng.standard_normal((ref.n + 1, robot.n_joints))
    last_present: list[np.ndarray] = [np.zeros(robot.n_joints)]

    def present() -> np.ndarray:  # what a deployment read before the tick (last_present)
        return last_present[0]

    probe = Session(registry()[solver].make(robot), robot, ref)
    imu = StillImu(probe.targets(0).torso_rotation)
    fall = FallDetector(FallParams(), (ref.foot.length, ref.foot.width))
    stab = Stabilizer(robot, ref.com_height, present, imu, fall=fall)
    stab.calibration = ImuCalibration(np.zeros(3), np.eye(3), 0.0, 1)  # applied every tick
    steps = StepAdjuster(robot, ref, SteppingParams())
    session = Session(registry()[solver].make(robot), robot, ref, stabilizer=stab,
                      stepping=steps)  # fmt: skip
    fb, sv, rd = [], [], []
    for i in range(ref.n):
        last_present[0] = session.q[7:] + noise[i]  # the servos' read, outside the tick
        session.tick(i)
        fb.append(session.feedback_time + session.stepping_time)
        sv.append(session.solve_time)
        rd.append(stab.read_time)
    fb, sv, rd = np.array(fb[5:]), np.array(sv[5:]), np.array(rd[5:])  # (warm caches)
    own = fb - rd  # without the sensor reads (the IMU driver's sample, the positions)
    return (float(np.median(fb / (fb + sv))), float(np.median(own / (own + sv))),
            float(np.median(fb)), float(np.median(sv)))  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--solvers", nargs="+", default=["wqp-daqp", "hqp-daqp", "placo", "pink"])
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    robot = load_robot("bioloid")
    ref = traj.build("walk10_wb", robot)
    print(f"{'solver':<10} {'share':>7} {'w/o reads':>10} {'feedback µs':>12} {'solve µs':>9}"
          "  target ≤ 30 %")  # fmt: skip
    for solver in args.solvers:
        runs = [measure(solver, robot, ref) for _ in range(args.repeats)]
        share, own, fb, sv = min(runs)
        met = "met" if share <= 0.30 else "NOT met"
        print(f"{solver:<10} {100 * share:6.1f}% {100 * own:9.1f}% {1e6 * fb:12.1f} "
              f"{1e6 * sv:9.1f}  {met}")  # fmt: skip


if __name__ == "__main__":
    main()
