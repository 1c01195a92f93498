"""The closed loop's share of a control tick: step adjustment + estimator + feedback vs the solve.

Runs ``walk10_wb`` (or ``--walks``) through :class:`wbc.walking.loop.Session` fed by a
:class:`wbc.balance.live.SessionSource` (what :func:`wbc.balance.live.closed_loop` builds,
the deployment's loop replaced by a plain loop over the ticks) with a
:class:`wbc.balance.stabilizer.Stabilizer` (default gains, the fall detector, a finished
start-up calibration applied to every sample), the step adjustment
(:class:`wbc.balance.stepping.StepAdjuster`) and the lift-off hold
(:class:`wbc.balance.retime.PhaseHold`): issue 30's default loop. The sensors are in-memory
ones (present positions = the controller's own joints + 0.29° noise, stored before each tick
as a deployment's ``last_present`` is; a still IMU at the reference torso orientation: the
estimator and the feedback do all their work, no simulator runs). Printed per family: the
share of the tick, :func:`wbc.balance.live.loop_share` — the definition the physics
benchmark's summary lines report too (per tick, loop / (loop + solve), the median; the
drivers' sensor reads not counted) — the best of ``--repeats`` runs, and the medians in µs of
the loop, the reads and the controller's tick (solve + integration), against issue 30's
target (≤ 30 % of a tick). The compiled ticks are waited for (``WBC_WAIT_FOR_COMPILE``): on
the numpy path the solve is 4–6× slower and the share looks 2× smaller than it is.

    python benchmarks/closed_loop_cost.py [--solvers hqp-daqp wqp-daqp placo pink]
        [--walks walk10 walk10_wb] [--repeats 3] [--against ROOT]

``--against ROOT`` measures another checkout side by side (its runs alternate with this one's,
a subprocess with ``PYTHONPATH=ROOT``): the before / after of a change in one run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("WBC_WAIT_FOR_COMPILE", "1")  # time the compiled ticks, not the interim

import numpy as np

from wbc import load_robot
from wbc.balance.fall import FallDetector, FallParams
from wbc.balance.live import SessionSource
from wbc.balance.retime import PhaseHold
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
    """One run along ``ref``: (share, loop µs, reads µs, solve µs; medians)."""
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
                      stepping=steps, hold=PhaseHold())  # fmt: skip
    source = SessionSource(session)
    for i in range(ref.n):
        last_present[0] = session.q[7:] + noise[i]  # the servos' read, outside the tick
        if source(i, float(ref.t[i] - ref.t[0])) is None:
            break
    skip = 5  # (warm caches)
    share = source.cost_share(skip)
    fb, rd, sv = (1e6 * float(np.median(x[skip:]))
                  for x in (source.feedback_time, source.read_time, source.solve_time))  # fmt: skip
    return share, fb, rd, sv


def measure_all(walks: list[str], solvers: list[str]) -> dict[str, tuple]:
    """One run of every (walk, solver): ``"walk solver"`` → :func:`measure`'s answer."""
    robot = load_robot("bioloid")
    out = {}
    for walk in walks:
        ref = traj.build(walk, robot)
        for solver in solvers:
            out[f"{walk} {solver}"] = measure(solver, robot, ref)
    return out


def against(root: Path, walks: list[str], solvers: list[str]) -> dict[str, tuple]:
    """:func:`measure_all` on the wbc checkout at ``root`` (this script in a subprocess with
    ``PYTHONPATH=root``; a checkout with :func:`wbc.balance.live.loop_share`)."""
    env = dict(os.environ, PYTHONPATH=str(root))
    cmd = [sys.executable, __file__, "--walks", *walks, "--solvers", *solvers, "--json"]
    text = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout
    return json.loads(text.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--solvers", nargs="+", default=["hqp-daqp", "wqp-daqp", "placo", "pink"])
    p.add_argument("--walks", nargs="+", default=["walk10_wb"])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--against", type=Path, metavar="ROOT",
                   help="another wbc checkout (its root), measured side by side: its run and "
                   "this one's alternate, repeat by repeat")  # fmt: skip
    p.add_argument("--json", action="store_true", help="one run, printed as one JSON line")
    args = p.parse_args()
    if args.json:
        print(json.dumps(measure_all(args.walks, args.solvers)))
        return
    runs: dict[str, list[list[tuple]]] = {"this": [], "against": []}
    for _ in range(args.repeats):
        runs["this"].append(list(measure_all(args.walks, args.solvers).items()))
        if args.against is not None:
            runs["against"].append(list(against(args.against, args.walks, args.solvers).items()))
    head = ["walk", "solver", "share", "loop µs", "reads µs", "solve µs"]
    if args.against is not None:
        head += ["ROOT: share", "loop µs", "solve µs"]
        print(f"ROOT: {args.against}")
    print(" | ".join(head) + " | target ≤ 30 %")
    for n, (key, _) in enumerate(runs["this"][0]):
        share, fb, rd, sv = min(r[n][1] for r in runs["this"])  # best of the repeats
        cells = [*key.split(), f"{100 * share:.1f} %", f"{fb:.1f}", f"{rd:.1f}", f"{sv:.1f}"]
        if args.against is not None:
            o_share, o_fb, _, o_sv = min(tuple(r[n][1]) for r in runs["against"])
            cells += [f"{100 * o_share:.1f} %", f"{o_fb:.1f}", f"{o_sv:.1f}"]
        print(" | ".join(cells) + (" | met" if share <= 0.30 else " | NOT met"))


if __name__ == "__main__":
    main()
