"""Which feedback keeps walk10 up best? Each variant of the closed loop on the nominal model.

Every row runs the controller live in the deployment's tick on the simulated Bioloid
(:func:`wbc.bench.physics.play_closed_loop`) and is measured against the controller's
open-loop plan (:func:`wbc.bench.physics.physics_record`): the largest torso deviation from
the plan (dev°) and from the reference's torso orientation (ref°), travelled / planned
distance, stance-sole slip, the estimator's largest tilt error and the loop's share of the
tick. ``--push`` adds the largest lateral impulse survived at mid single support (N·s).

    python benchmarks/closed_loop_choice.py --solver wqp-daqp [--push]
"""

from __future__ import annotations

import argparse

from wbc import load_robot
from wbc.balance.stabilizer import Gains
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import ClosedLoopSpec, simulate
from wbc.bench.pushes import largest_push
from wbc.bench.runner import run_entry
from wbc.bench.solvers import registry

OFF = dict(k_p=0.0, k_d=0.0, k_yaw=0.0)
#: label -> (compliance gain, gains, IMU used, loop on); None: the plan played open loop
VARIANTS: dict[str, tuple[float, dict, bool, bool] | None] = {
    "plan played open loop": None,
    "live, loop off": (0.0, {}, True, False),
    "compliance x0.5, loop off": (0.5, {}, True, False),
    "+ torso P 1.5": (0.5, dict(OFF, k_p=1.5), True, True),
    "+ torso PD 1.5 / 0.1": (0.5, dict(OFF, k_p=1.5, k_d=0.1), True, True),
    "+ heading (default)": (0.5, {}, True, True),
    "default + integral 1/s": (0.5, dict(k_i=1.0), True, True),
    "default + DCM 0.15": (0.5, dict(k_dcm=0.15), True, True),
    "default + DCM 0.3": (0.5, dict(k_dcm=0.3), True, True),
    "default + CoM lean 1": (0.5, dict(k_lean=1.0), True, True),
    "default + joint level 1 / 0.1": (0.5, dict(j_p=1.0, j_d=0.1), True, True),
    "DCM 0.3 alone": (0.5, dict(OFF, k_dcm=0.3), True, True),
    "default, encoders only": (0.5, {}, False, True),
    "default, no compliance": (0.0, {}, True, True),
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--solver", default="wqp-daqp")
    p.add_argument("--trajectory", default="walk10")
    p.add_argument("--push", action="store_true")
    p.add_argument("--only", nargs="*", help="variant labels to run (default: all)")
    args = p.parse_args()
    robot = load_robot("bioloid")
    ref = traj.build(args.trajectory, robot)
    entry = registry()[args.solver]
    _, rec = run_entry(entry, robot, ref, "tick")
    print(f"{args.solver} on {args.trajectory}")
    print("| feedback | fell | dev° | ref° | dist | slip mm | est. tilt° | share | push lat N·s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for label, variant in VARIANTS.items():
        if args.only and label not in args.only:
            continue
        comp, spec = 0.0, None
        if variant is not None:
            comp, gains, imu, on = variant
            spec = ClosedLoopSpec(entry.make, ref, Gains(**gains), on, imu)
        r = simulate(rec, robot, compensate=comp, closed=spec)
        push = "-"
        if args.push:
            v = largest_push(rec, robot, "lateral", compensate=comp, closed=spec)
            push = "fell" if v is None else f"{v:.3f}"
        fell = f"{r['fall_time_s']:.2f}" if r["fell"] else "-"
        dist = "-" if r["distance_ratio"] is None else f"{r['distance_ratio']:.2f}"
        ref_dev = r.get("torso_ref_dev_max_deg")
        tilt = r.get("estimated_tilt_max_deg")
        share = r.get("feedback_share")
        print(
            f"| {label} | {fell} | {r['orientation_dev_max_deg']:.1f} | "
            f"{'-' if ref_dev is None else f'{ref_dev:.1f}'} | {dist} | "
            f"{r['foot_slip_max_mm']:.1f} | {'-' if not tilt else f'{tilt:.1f}'} | "
            f"{'-' if not share else f'{100 * share:.0f} %'} | {push} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
