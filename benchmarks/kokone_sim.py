"""Kokone in the simulator: how the physics figures depend on the hobby servo's estimates.

    python benchmarks/kokone_sim.py                      # the sweep (benchmarks/kokone_sim.md)
    python benchmarks/kokone_sim.py --trajectories keyposes --bands 20 40
    python benchmarks/kokone_sim.py --timesteps          # the figures at 2, 1 and 0.5 ms
    python benchmarks/kokone_sim.py --speed              # simulated s per wall s
    python benchmarks/kokone_sim.py --stand              # standing still: band vs oscillation
    python benchmarks/kokone_sim.py --stand --bands 20 30 40 60 --damping 0.5 0.75 1 1.5

Each trajectory is planned once by ``hqp-daqp`` (the ``walk`` stack), then played through the
SSC-32 backend on the simulator (:func:`wbc.bench.play.play`, as ``wbc bench --physics
--robot kokone``) with the nominal servo of ``robots/kokone/robot.toml`` ``[servo]`` changed
in one estimate at a time: the proportional band (µs of pulse to full torque), and the drive
update (analog: once per 20 ms pulse; "digital": every 4 ms, the same torque and speed).
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from wbc import load_robot
from wbc.bench.physics import plan
from wbc.bench.play import play
from wbc.bench.sim_record import physics_record
from wbc.sim.actuator import nominal_servo
from wbc.sim.model import ModelParams


def row(label: str, rec, robot, **kw) -> str:
    r = physics_record(rec, play(rec, robot, settle=1.0, limit_tol=math.inf, **kw), robot)
    fell = f"{r['fall_time_s']:.2f} ({r['fall_phase']})" if r["fell"] else "-"
    dist = "-" if r["distance_ratio"] is None else f"{r['distance_ratio']:.2f}"
    return (
        f"| {label} | {fell} | {r['orientation_dev_max_deg']:.1f} | {dist} | "
        f"{r['foot_slip_max_mm']:.1f} | {r['tracking_err_max_deg']:.1f} {r['tracking_joint']} | "
        f"{r['torque_peak_ratio']:.2f} {r['torque_joint']} |"
    )


HEADER = (
    "| servo | fell at s (phase) | dev° | dist | slip mm | err° (joint) | τ/τ_stall (joint) |\n"
    "|---|---|---|---|---|---|---|"
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--trajectories", nargs="+", default=["keyposes", "thesis_step", "walk10", "lateral"]
    )
    parser.add_argument("--bands", nargs="+", type=float, default=[10, 20, 40, 100])
    parser.add_argument("--timesteps", action="store_true", help="nominal at 2, 1, 0.5 ms")
    parser.add_argument("--speed", action="store_true", help="simulated s per wall s")
    parser.add_argument("--stand", action="store_true", help="3 s standing per servo variant")
    parser.add_argument(
        "--damping", nargs="+", type=float, default=None,
        help="--stand: analog servos only, x these back-EMF damping factors (a column each)",
    )  # fmt: skip
    args = parser.parse_args()
    robot = load_robot("kokone")
    nominal = nominal_servo(robot)
    print(f"{platform.node()} {platform.machine()}, Python {platform.python_version()}")
    if args.stand and args.damping:
        stand_damping(robot, nominal, args.bands, args.damping)
        return
    if args.stand:
        stand(robot, nominal, args.bands)
        return
    if args.speed:  # the Bioloid's walk10 through the same path, same run: the ratio's base
        bioloid = load_robot("bioloid")
        rec = plan("hqp-daqp", "walk10", bioloid)
        started = time.perf_counter()
        result = play(rec, bioloid, settle=1.0, limit_tol=math.inf)
        wall = time.perf_counter() - started
        sim_s = float(result.log["t"][-1])
        print(f"Bioloid walk10 (AX-12A bus): {sim_s:.1f} s simulated in {wall:.2f} s wall = "
              f"{sim_s / wall:.1f}× real time")  # fmt: skip
    for name in args.trajectories:
        rec = plan("hqp-daqp", name, robot)
        print(f"\n**{name}** (hqp-daqp's plan, {rec.t[-1] - rec.t[0]:.1f} s)\n")
        print("" if args.speed else HEADER)
        if args.speed:
            started = time.perf_counter()
            result = play(rec, robot, settle=1.0, limit_tol=math.inf)
            wall = time.perf_counter() - started
            sim_s = float(result.log["t"][-1])
            rate = result.sim.steps / wall
            print(f"nominal: {sim_s:.1f} s simulated in {wall:.2f} s wall = "
                  f"{sim_s / wall:.1f}× real time, {rate:.0f} steps/s")  # fmt: skip
            continue
        if args.timesteps:
            for dt in (0.002, 0.001, 0.0005):
                print(row(f"nominal, {dt * 1e3:g} ms step", rec, robot,
                          model_params=ModelParams(timestep=dt)))  # fmt: skip
            continue
        for band in args.bands:
            for label, loop in (("analog", None), ("digital 4 ms", 0.004)):
                sp = replace(nominal, proportional_band_us=band, loop_period=loop)
                mark = " (nominal)" if band == nominal.proportional_band_us and loop is None else ""
                text = f"{label}, band {band:g} µs = {band / 13.33:.1f}°{mark}"
                print(row(text, rec, robot, servo_params=sp), flush=True)
        stiff = replace(nominal, proportional_band_us=4.0, dead_band_us=1.0, loop_period=0.002)
        print(row("stiff reference: band 4 µs, dead band 1 µs, 2 ms loop", rec, robot,
                  servo_params=stiff))  # fmt: skip


def stand(robot, nominal, bands) -> None:
    """Kokone holding its crouch for 3 s (pulses at the crouch): torso tilt and the largest
    joint speed over the last 2 s (a servo loop that oscillates shows here)."""
    import numpy as np

    from wbc.sim.simulator import Simulation

    print("\n| servo | torso tilt after 3 s (°) | max joint speed, last 2 s (rad/s) |")
    print("|---|---|---|")
    for band in sorted({5.0, *bands}):
        for label, loop in (("analog", None), ("digital 4 ms", 0.004)):
            sp = replace(nominal, proportional_band_us=band, loop_period=loop)
            sim = Simulation(robot, servo_params=sp)
            sim.write_goals(np.rint(sim.servos.pulses(sim.q()[7:])))
            R0 = sim.base_rotation()
            sim.advance(1.0)
            speed = 0.0
            for _ in range(100):
                sim.advance(0.02)
                speed = max(speed, float(np.abs(sim.joint_velocities()).max()))
            R = sim.base_rotation()
            tilt = math.degrees(math.acos(np.clip((np.trace(R0.T @ R) - 1) / 2, -1, 1)))
            print(f"| {label}, band {band:g} µs | {tilt:.1f} | {speed:.2f} |")


def stand_speed(robot, model_params: ModelParams, servo_params) -> float:
    """The largest joint speed (rad/s) over the last 2 of 3 s holding the standing pose
    (pulses at the pose from the start) on this plant (above ~1: the servo loop oscillates)."""
    import numpy as np

    from wbc.sim.simulator import Simulation

    sim = Simulation(robot, model_params, servo_params)
    sim.write_goals(np.rint(sim.servos.pulses(sim.q()[7:])))
    sim.advance(1.0)
    speed = 0.0
    for _ in range(100):
        sim.advance(0.02)
        speed = max(speed, float(np.abs(sim.joint_velocities()).max()))
    return speed


def stand_damping(robot, nominal, bands, factors) -> None:
    """The analog servo's crouch held 3 s for each proportional band and back-EMF damping
    factor (the randomised plants' ranges): the largest joint speed over the last 2 s
    (rad/s; above ~1: the servo loop oscillates)."""
    print("\n| band | " + " | ".join(f"damping x{d:g}" for d in factors) + " |")
    print("|---" * (len(factors) + 1) + "|")
    for band in bands:
        cells = []
        for d in factors:
            sp = replace(nominal, proportional_band_us=band)
            speed = stand_speed(robot, ModelParams(damping=nominal.damping * d), sp)
            cells.append(f"{speed:.2f}")
        print(f"| {band:g} µs | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
