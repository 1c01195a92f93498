"""Why Kokone falls on randomised models: one part of each random draw at a time
(benchmarks/kokone_sim.md section 000).

    python benchmarks/kokone_random.py --trajectory walk10_wb -n 10
    python benchmarks/kokone_random.py --robot /tmp/copy/kokone --parts all servo
    python benchmarks/kokone_random.py --trajectory fast_wb --draws 1 6 8

The plan (hqp-daqp) is played open loop with the robot's default feed-forward
(``wbc.balance.best_compensate``: x1 on hobby PWM servos) on ``n`` draws of
``wbc.bench.variation.models`` (the draws of ``wbc bench --physics --robustness n --seed S``
and of ``benchmarks/robots.py --random n``; ``--draws``: only those of them). For each draw,
the whole draw (``all``) and then one part of it on the otherwise nominal model: ``servo`` (the
proportional band and stall torque), ``noservo`` (the whole draw but the servo's band and stall
torque nominal), ``stiff`` (the band alone), ``torque`` (the stall torque alone), ``joint``
(armature, back-EMF damping, gear friction), ``mass`` (link masses), ``com`` (link CoM
offsets), ``latency``, ``floor`` (floor friction). A cell is the max base orientation deviation
from plan (deg) or ``F<t>``: fell at t s. Column ``stand``: the whole draw holding the standing
pose 3 s, the largest joint speed over the last 2 s (rad/s; above ~1 the servo loop oscillates:
a buzzing servo), as ``benchmarks/kokone_sim.py --stand``.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

from wbc.balance import best_compensate
from wbc.bench.physics import plan
from wbc.bench.play import play
from wbc.bench.sim_record import physics_record
from wbc.bench.variation import Variation, models
from wbc.model import load_robot
from wbc.sim.actuator import nominal_servo
from wbc.sim.model import ModelParams

PARTS = (
    "stand",
    "all",
    "noservo",
    "servo",
    "stiff",
    "torque",
    "joint",
    "mass",
    "com",
    "latency",
    "floor",
)


def part_kwargs(part: str, v: Variation, nominal) -> dict:
    """``play`` keyword arguments with only ``part`` of the draw ``v`` (module docstring)."""
    mp, sp, s = v.model_params, v.servo_params, v.summary
    if part == "all":
        return v.play_kwargs()
    if part == "noservo":
        kw = v.play_kwargs()
        band, torque = nominal.proportional_band_us, nominal.stall_torque
        kw["servo_params"] = replace(sp, proportional_band_us=band, stall_torque=torque)
        return kw
    if part == "servo":
        band, torque = sp.proportional_band_us, sp.stall_torque
        return {"servo_params": replace(nominal, proportional_band_us=band, stall_torque=torque)}
    if part == "stiff":
        band = nominal.proportional_band_us / s["stiffness"]
        return {"servo_params": replace(nominal, proportional_band_us=band)}
    if part == "torque":
        return {"servo_params": replace(nominal, stall_torque=sp.stall_torque)}
    if part == "joint":
        model = ModelParams(
            armature=mp.armature, damping=mp.damping, friction_loss=mp.friction_loss
        )
        servo = replace(nominal, armature=sp.armature, friction_loss=sp.friction_loss)
        return {"model_params": model, "servo_params": servo}
    if part == "mass":
        return {"model_params": ModelParams(mass_scale=mp.mass_scale)}
    if part == "com":
        return {"model_params": ModelParams(com_offset=mp.com_offset)}
    if part == "latency":
        return {"latency_s": v.latency_s}
    if part == "floor":
        return {"model_params": ModelParams(floor_friction=mp.floor_friction)}
    raise ValueError(f"unknown part {part!r}; choose from {PARTS}")


def stand_speed(robot, v: Variation) -> float:
    """The largest joint speed (rad/s) over the last 2 of 3 s holding the standing pose on the
    draw ``v`` (:func:`kokone_sim.stand_speed`)."""
    from kokone_sim import stand_speed as held

    return held(robot, v.model_params, v.servo_params)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="kokone")
    parser.add_argument("--trajectory", default="walk10_wb")
    parser.add_argument("-n", type=int, default=10, help="randomised draws")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--parts", nargs="+", default=list(PARTS), choices=PARTS)
    parser.add_argument("--draws", nargs="+", type=int, help="only these of the n draws")
    args = parser.parse_args()
    robot = load_robot(args.robot)
    rec = plan("hqp-daqp", args.trajectory, robot)
    ff = best_compensate(robot)
    nominal = nominal_servo(robot)

    def cell(kwargs: dict) -> tuple[str, bool]:
        r = physics_record(rec, play(rec, robot, compensate=ff, **kwargs), robot)
        if r["fell"]:
            return f"F{r['fall_time_s']:.1f}", True
        return f"{r['orientation_dev_max_deg']:.1f}", False

    print(f"{robot.name} {args.trajectory}: nominal {cell({})[0]}")
    print("| draw | stiffness | torque | " + " | ".join(args.parts) + " |")
    print("|---" * (len(args.parts) + 3) + "|")
    falls = dict.fromkeys(args.parts, 0)
    draws = models(robot, args.n, args.seed)
    chosen = range(args.n) if args.draws is None else args.draws
    for i in chosen:
        v = draws[i]
        cells = []
        for part in args.parts:
            if part == "stand":
                speed = stand_speed(robot, v)
                falls[part] += speed > 1.0
                cells.append(f"{speed:.2f}")
                continue
            text, fell = cell(part_kwargs(part, v, nominal))
            falls[part] += fell
            cells.append(text)
        s = v.summary
        row = [str(i), f"{s['stiffness']:.2f}", f"{s['torque']:.2f}", *cells]
        print("| " + " | ".join(row) + " |", flush=True)
    print("| fell | | | " + " | ".join(f"{falls[p]}/{len(chosen)}" for p in args.parts) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
