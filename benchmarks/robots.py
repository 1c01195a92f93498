"""Three robots side by side: the Bioloid, Kokone and a robot made here (benchmarks/robots.md).

The third robot is the Bioloid's URDF with other proportions and ROBOTIS OP3 joint names:
legs 1.3x longer (masses 1.3³, inertias 1.3⁵, the AX-12A servos kept), torso and arms 0.8x,
standing in the pose ``wbc robot init`` proposes (hips at 92 % of the leg length). Roles,
feet, legs and walking settings are read from the model; its ``robot.toml`` states only what
was measured on it: the closed loop's dead bands and push trigger (:data:`STEPPING`).

    python benchmarks/robots.py --out /tmp/longlegs            # make the robot, then measure
    python benchmarks/robots.py --out /tmp/longlegs --random 5 # + 5 randomised sim models
    python benchmarks/robots.py --out /tmp/ll --trajectories static_walk \\
        --robot-toml '[walking.static_walk]\\nstep_length = 0.021'  # a stated setting

Columns: kinematic (the robot's stack, one QP per tick: CoM / swing-sole error max, mm; the
ZMP margin min of the tracked motion, mm; the reference's peak joint speed as a share of the
no-load speed, and its predicted peak joint torque as a share of stall,
`wbc.walking.feasibility`); simulator, ``wbc bench --physics``'s two rows: the plan
(hqp-daqp) played open loop, and the controller run live closed through the IMU (the robot's
default: step adjustment unless its servos report no position or it states no dead bands),
both with the servo feed-forward at its measured best for the robot's servo law
(`wbc.balance.best_compensate`: x0.5 AX-12A, x1 hobby PWM). Nominal servo model: fell at s
or "-", max base orientation deviation from plan, deg, travelled / planned distance, the
peak servo torque over its stall (τ/τs); randomised models (``wbc bench --robustness N
--seed S``'s draws, `wbc.bench.variation.models`): fell or stopped count (the deployment's
stops, e.g. its start-up IMU check, in brackets), median deviation and median travelled over
the runs that stayed up.

    python benchmarks/robots.py --out /tmp/ll --random 20 --robots bioloid kokone longlegs op3
"""

from __future__ import annotations

import argparse
import re
import shutil
import time
from pathlib import Path

import numpy as np

from wbc.balance import best_compensate
from wbc.bench import metrics
from wbc.bench.closed_loop import ClosedLoopSpec
from wbc.bench.closed_loop import simulate as closed_loop_simulate
from wbc.bench.physics import physics_entry, plan
from wbc.bench.trajectories import build
from wbc.bench.variation import models
from wbc.exceptions import WbcError
from wbc.model import load_robot
from wbc.paths import robots_dir
from wbc.recording import Recording
from wbc.robot_folder import standing_pose
from wbc.stacks import load_stack, robot_stack
from wbc.urdf_writer import transform_urdf
from wbc.walking.feasibility import kinematic_feasibility
from wbc.walking.loop import StackController, run

#: Bioloid joint suffix -> ROBOTIS OP3 name suffix
OP3 = {
    "hip_yaw": "hip_yaw",
    "hip_roll": "hip_roll",
    "hip_pitch": "hip_pitch",
    "knee": "knee",
    "ankle_pitch": "ank_pitch",
    "ankle_roll": "ank_roll",
    "shoulder_pitch": "sho_pitch",
    "shoulder_roll": "sho_roll",
    "elbow": "el",
}
LEG_LINKS = ("hip_bracket", "hip_block", "thigh", "shin", "ankle_block", "foot", "sole")
TRAJECTORIES = ("static_walk", "walk10_wb")
ROBOTS = ("bioloid", "kokone", "longlegs")
LOOPS = ("open", "closed")
#: the long-legged robot's ``[balance.stepping]``, measured on it (benchmarks/robots.md,
#: 2026-12-06 third round): its unpushed walk10_wb's DCM error in single support, closed loop
#: with nothing re-planned, nominal and the 20 plants of ``--random 20``, reaches 71.1 mm along
#: the walk and 89.8 mm sideways (plant 0; nominal 24.6 / 41.0), its largest jump in one tick
#: 33.4 mm (plant 0; nominal 7.8): the bands and the trigger just above
STEPPING = "[balance.stepping]\nband_x = 0.075\nband_y = 0.09\ntrigger_jump = 0.036\n"


def make_robot(out: Path, legs: float = 1.3, body: float = 0.8, robot_toml: str = "") -> Path:
    """Write the long-legged robot's folder (module docstring) to ``out``; its ``robot.toml``
    states :data:`STEPPING` and ``robot_toml`` (more of it: TOML text)."""
    src = robots_dir() / "bioloid"
    bioloid = load_robot("bioloid")
    names = {j: j[:2] + OP3[j[2:]] for j in bioloid.joint_names}

    def scale(link: str) -> float:
        return legs if link[2:] in LEG_LINKS else body

    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    text = transform_urdf((src / "bioloid.urdf").read_text(), scale, names, torque_exponent=0)
    (out / f"{out.name}.urdf").write_text(text)
    servos = (src / "servos.toml").read_text()
    for old, new in names.items():
        servos = re.sub(rf"(?<![A-Za-z0-9_]){old}(?![A-Za-z0-9_])", new, servos)
    (out / "servos.toml").write_text(servos)
    (out / "robot.toml").write_text(STEPPING + robot_toml)
    robot = load_robot(out)
    pose = standing_pose(robot)
    (out / "poses.toml").write_text(
        "[poses.walk_ready]\n"
        + "".join(f"{j} = {float(v)!r}\n" for j, v in zip(robot.joint_names, pose, strict=True))
    )
    return out


def kinematic(robot, name: str) -> dict[str, object]:
    try:
        ref = build(name, robot)
    except WbcError as exc:
        return {"error": str(exc).split(":")[-1].strip()[:60]}
    report = kinematic_feasibility(robot, ref, iterations=2)
    rec = run(StackController(load_stack(robot_stack(robot)[0], robot)), robot, ref)
    m = metrics.compute(rec, robot)
    return {
        "duration": ref.duration,
        "com": m["com_err_max_mm"],
        "foot": m["foot_err_max_mm"],
        "zmp": m["zmp_margin_min_mm"],
        "speed": report.speed_fraction,
        "torque": report.torque_fraction,
        "fail": m["failures"],
    }


def closed_spec(robot, ref) -> ClosedLoopSpec:
    """The robot's closed loop as ``wbc bench --physics`` runs it: hqp-daqp on the robot's
    stack, live through the IMU; step adjustment unless its servos report nothing."""
    from wbc.balance.stepping import SteppingParams
    from wbc.sim.actuator import servo_kind

    step = None if servo_kind(robot) == "hobby_pwm" else SteppingParams()
    return ClosedLoopSpec(physics_entry("hqp-daqp", robot).make, ref, None, True, True, step)


def simulate(
    robot, name: str, n_random: int, seed: int = 0, loop: str = "open"
) -> dict[str, object]:
    """The plan (hqp-daqp) in the simulator, ``loop`` open or closed (``wbc bench
    --physics``'s two rows, the feed-forward at the robot's best), on the nominal model and on
    ``n_random`` randomised ones: ``wbc bench --robustness n_random --seed seed``'s draws."""
    try:
        ref = build(name, robot, on_servos=True)  # as plan() plays it
        rec: Recording = plan("hqp-daqp", name, robot)
    except WbcError as exc:
        return {"error": str(exc)[:60]}
    kw = {
        "compensate": best_compensate(robot),  # the default feed-forward for the servo law
        "closed": closed_spec(robot, ref) if loop == "closed" else None,
    }

    def one(v) -> dict:
        r = closed_loop_simulate(rec, robot, v, **kw)
        r["up"] = not r["fell"] and r["stopped"] is None
        return r

    nominal = one(None)
    out = {
        "fell": nominal["fall_time_s"] if nominal["fell"] else None,
        "dev": nominal["orientation_dev_max_deg"],
        "dist": nominal.get("distance_ratio", float("nan")),
        "torque": nominal["torque_peak_ratio"],
    }
    runs = [one(v) for v in models(robot, n_random, seed)]
    if runs:  # deviation and distance: medians over the runs that stayed up
        up = [r for r in runs if r["up"]]
        devs = [r["orientation_dev_max_deg"] for r in up]
        dists = [r["distance_ratio"] for r in up if r.get("distance_ratio") is not None]
        stopped = sum(1 for r in runs if r["stopped"] is not None and not r["fell"])
        down = f"{len(runs) - len(up)}/{n_random}"
        out.update(
            random=down + (f" ({stopped} stopped)" if stopped else ""),
            reasons=sorted({str(r["stopped"]) for r in runs if r["stopped"] and not r["fell"]}),
            rdev=float(np.median(devs)) if devs else float("nan"),
            rdist=float(np.median(dists)) if dists else float("nan"),
            down=[k for k, r in enumerate(runs) if not r["up"]],
        )
    return out


def _num(v: object, digits: int) -> str:
    return f"{v:.{digits}f}" if isinstance(v, (int, float)) and np.isfinite(v) else "-"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="folder for the made robot")
    parser.add_argument("--random", type=int, default=0, help="randomised sim models per run")
    parser.add_argument("--seed", type=int, default=0, help="the randomised models' seed")
    parser.add_argument("--trajectories", nargs="+", default=list(TRAJECTORIES))
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS), help="folders or names")
    parser.add_argument("--loops", nargs="+", default=["open", "closed"], choices=LOOPS)
    parser.add_argument("--no-sim", action="store_true")
    parser.add_argument(
        "--robot-toml", default="", help="a robot.toml for the made robot (TOML text; \\n allowed)"
    )
    args = parser.parse_args()
    robots = {}
    for name in args.robots:
        if name == "longlegs":
            made = make_robot(args.out, robot_toml=args.robot_toml.replace("\\n", "\n"))
            robots[name] = load_robot(made)
        else:
            robots[name] = load_robot(name)
    for name, robot in robots.items():
        legs = robot.roles.leg("left")
        print(f"## {name}: {robot.total_mass:.3f} kg, legs {legs}, feet {robot.foot_size}")
    print(
        "| robot | trajectory | s | CoM err mm | swing err mm | ZMP margin mm | speed share "
        "| torque share "
        "| loop | sim fell at s | dev° | dist | τ/τs | random fell | rdev° | rdist |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for t in args.trajectories:
        for name, robot in robots.items():
            t0 = time.time()
            k = kinematic(robot, t)
            if "error" in k:
                print(f"| {name} | {t} | refused: {k['error']} ||||||||||||||")
                continue
            cells = [
                name,
                t,
                f"{k['duration']:.1f}",
                f"{k['com']:.3f}",
                f"{k['foot']:.3f}",
                f"{k['zmp']:.1f}",
                f"{k['speed']:.2f}",
                f"{k['torque']:.2f}",
            ]
            for loop in [] if args.no_sim else args.loops:
                s = simulate(robot, t, args.random, args.seed, loop)
                row = [*cells, loop]
                if "error" in s:
                    row += [f"sim: {s['error']}", "", "", "", "", "", ""]
                else:
                    row += ["-" if s["fell"] is None else f"{s['fell']:.2f}"]
                    row += [_num(s["dev"], 1), _num(s["dist"], 2), _num(s["torque"], 2)]
                    row += [str(s.get("random", "")), _num(s.get("rdev"), 1)]
                    row += [_num(s.get("rdist"), 2)]
                print("| " + " | ".join(row) + " |", flush=True)
                if s.get("down"):
                    print(f"<!-- {name} {t} {loop}: down on draws {s['down']} -->", flush=True)
                for reason in s.get("reasons", []):
                    print(f"<!-- {name} {t} {loop}: stopped: {reason} -->", flush=True)
            if args.no_sim:
                print("| " + " | ".join([*cells, *[""] * 8]) + " |", flush=True)
            print(f"<!-- {name} {t}: {time.time() - t0:.0f} s -->", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
