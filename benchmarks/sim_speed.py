"""Speed of the simulated Bioloid (benchmarks/physics.md quotes this script's output).

    python benchmarks/sim_speed.py [--seconds 10] [--sweep 10]
    python benchmarks/sim_speed.py --timesteps      # the physics figures vs the time step

1. physics only: :meth:`Simulation.advance` standing at Walk Ready (servo law + MuJoCo step);
2. the deploy path: ``walk10`` planned by ``hqp-daqp``, played by :func:`wbc.bench.play.play`
   (deployment safety layer, per-tick logging of the state and contact forces);
3. a sweep: the same run on N randomised models (``wbc bench --physics --robustness N``).

Reported as simulated seconds per wall second ("× real time") and physics steps per second.
"""

from __future__ import annotations

import argparse
import platform
import time

from wbc import load_robot
from wbc.bench.closed_loop import robustness
from wbc.bench.physics import plan
from wbc.bench.play import play
from wbc.sim.simulator import Simulation


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated s, part 1")
    parser.add_argument("--sweep", type=int, default=10, help="models in part 3 (0: skip)")
    parser.add_argument(
        "--timesteps", action="store_true", help="hqp-daqp's physics record at 2, 1, 0.5 ms"
    )
    args = parser.parse_args()
    robot = load_robot("bioloid")
    print(f"{platform.node()} {platform.machine()}, Python {platform.python_version()}")
    if args.timesteps:
        timestep_check(robot)
        return

    sim = Simulation(robot)
    sim.set_torque(True)
    sim.advance(0.1)  # compile and warm up
    steps0, start = sim.steps, time.perf_counter()
    sim.advance(args.seconds)
    wall = time.perf_counter() - start
    steps = sim.steps - steps0
    print(f"1. physics only, standing: {steps / wall:,.0f} steps/s "
          f"(dt {sim.dt * 1e3:g} ms) = {args.seconds / wall:.1f} x real time")  # fmt: skip
    q = sim.data.qpos[sim.qadr].copy()
    timing = {}
    for name, law in (("compiled", sim.servos.law), ("numpy", sim.servos.law_numpy)):
        start = time.perf_counter()
        for _ in range(5000):
            law(q, sim.dt)
        timing[name] = (time.perf_counter() - start) / 5000 * 1e6
    start = time.perf_counter()
    for _ in range(2000):
        sim.mj.mj_step(sim.model, sim.data)
    mj_us = (time.perf_counter() - start) / 2000 * 1e6
    print(f"   servo law per step (18 joints): compiled {timing['compiled']:.1f} us, numpy "
          f"{timing['numpy']:.1f} us; mj_step {mj_us:.1f} us")  # fmt: skip

    rec = plan("hqp-daqp", "walk10", robot)
    start = time.perf_counter()
    result = play(rec, robot, settle=1.0)
    wall = time.perf_counter() - start
    simulated = result.log["t"][-1]
    print(
        f"2. walk10 through the deploy path: {simulated:.2f} s simulated in {wall:.2f} s = "
        f"{simulated / wall:.1f} x real time ({result.sim.steps / wall:,.0f} steps/s)"
    )

    if args.sweep:
        start = time.perf_counter()
        r = robustness(rec, robot, args.sweep, seed=0)
        wall = time.perf_counter() - start
        print(f"3. walk10 sweep, {args.sweep} randomised models: {wall:.1f} s "
              f"({wall / args.sweep:.2f} s per model; 50 models ~ {50 * wall / args.sweep:.0f} s); "
              f"up fraction {r['up_fraction']:.2f}")  # fmt: skip


def timestep_check(robot) -> None:
    """The physics figures of hqp-daqp's plans at 2 ms (default), 1 ms and 0.5 ms steps."""
    from wbc.bench.sim_record import physics_record
    from wbc.sim.model import ModelParams

    keys = ("orientation_dev_max_deg", "distance_ratio", "foot_slip_max_mm",
            "tracking_err_max_deg", "torque_peak_ratio", "cop_margin_min_mm")  # fmt: skip
    print("trajectory   dt ms  " + "  ".join(keys))
    for trajectory in ("thesis_step", "walk10"):
        rec = plan("hqp-daqp", trajectory, robot)
        for dt in (0.002, 0.001, 0.0005):
            r = physics_record(rec, play(rec, robot, ModelParams(timestep=dt)), robot)
            values = "  ".join(f"{r[k]:.4g}" if r[k] is not None else "-" for k in keys)
            print(f"{trajectory:<12} {dt * 1e3:5.1f}  {values}")


if __name__ == "__main__":
    main()
