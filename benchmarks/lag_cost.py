"""What measuring the servos' lag costs in the closed loop's tick (issue 30, i30p's eighth
round, benchmarks/physics.md).

First :func:`wbc.balance.servo_lag.servo_lag` alone inside compiled code (18 joints, a numba
loop of 10, 10³ and 10⁵ calls: ns per call); then the closed loop on the simulated nominal
Bioloid (``walk10_wb``, wqp-daqp, no feed-forward: the sweeps' default gains, 3 s), two rounds
alternating the lag unmeasured / measured (``Stabilizer.measure_lag``): the medians of the
loop's own part (estimator + feedback + step adjustment) and of the solve per tick (µs, the
first 20 walking ticks left out) and ``loop_share``.

    nice -n 5 python benchmarks/lag_cost.py
"""

from __future__ import annotations

import time

import numba
import numpy as np

from wbc import load_robot
from wbc.balance.live import closed_loop
from wbc.balance.servo_lag import lag_state, servo_lag
from wbc.balance.stabilizer import default_gains
from wbc.bench.solvers import select
from wbc.bench.trajectories import build
from wbc.sim.bus import SimImu, SimServoBus
from wbc.sim.simulator import Simulation
from wbc.walking.loop import start_configuration


@numba.njit
def _many(present: np.ndarray, goal: np.ndarray, state: np.ndarray, k: int) -> float:
    s = 0.0
    for _ in range(k):
        goal[0] += 1e-4
        s += servo_lag(present, goal, 0.01, state)
    return s


def main() -> None:
    n = 18
    state, goal = lag_state(n), np.linspace(0, 1, n)
    present = goal - 0.01
    for k in (10, 1000, 100000):
        _many(present, goal, state, k)
        start = time.perf_counter()
        _many(present, goal, state, k)
        print(f"servo_lag, {k} calls in compiled code: "
              f"{(time.perf_counter() - start) / k * 1e9:.0f} ns per call")  # fmt: skip
    robot = load_robot("bioloid")
    entry = select(["wqp-daqp"], None, "tick")[0][0]
    ref = build("walk10_wb", robot)
    for rnd in range(2):
        for measure in (False, True):
            sim = Simulation(robot)
            sim.reset(start_configuration(robot, ref))
            loop = closed_loop(SimServoBus(sim), robot, entry.make(robot), ref, SimImu(sim),
                               default_gains(0.0), compensate=0.0, out=lambda _l: None,
                               duration=3.0)  # fmt: skip
            loop.stabilizer.measure_lag = measure
            loop.deployment.run()
            fb = 1e6 * np.median(loop.source.feedback_time[20:])
            sv = 1e6 * np.median(loop.source.solve_time[20:])
            print(f"round {rnd}, lag measured {measure}: loop {fb:.1f} µs, solve {sv:.1f} µs, "
                  f"loop_share {loop.source.cost_share(20):.3f}, "
                  f"lag {1e3 * loop.stabilizer.servo_lag:.1f} ms")  # fmt: skip


if __name__ == "__main__":
    main()
