"""Rolling from the back onto the front (an experiment for the get-up from the back, issue 33):
the simulated robot dropped on its back (as ``benchmarks/getup.py`` drops it), then a
joint-space roll played through the deployment with the servos stiffened ``--stiffness``
× the configured (``ServoBus.set_stiffness``). Prints, per model, the torso front's (its x
axis's) vertical component over the roll (+1 face up, 0 on a side, −1 face down: prone) and
the side it ends on (:func:`wbc.balance.getup.lying_side`).

    nice -n 5 python benchmarks/getup_roll.py --models 5 --nominal

The roll (the best of the keyframe sequences tried, benchmarks/getup.md), by joint role (the
model's roles, no joint names), rolling towards the right: the left leg drawn up (foot
planted), the left arm alongside the body and the right arm above the head; the left arm
pushes the floor behind (shoulder pitched back) while the left leg extends and the right leg
is drawn up (the robot tips onto its right side); the arms and the left leg swing forward.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

os.environ.setdefault("WBC_WAIT_FOR_COMPILE", "1")

from wbc import load_robot
from wbc.balance.getup import lying_side
from wbc.bench.variation import models
from wbc.drive.getup_sim import drop
from wbc.drive.sim import make_sim
from wbc.model import Robot
from wbc.servos.playback import DeployConfig, Deployment
from wbc.servos.sources import CallableSource

#: (duration s, {("left"/"right", role): degrees}) — each keyframe changes the previous one
ROLL = [
    (0.8, {("left", "shoulder_roll"): -80, ("left", "hip_pitch"): -70, ("left", "knee"): 110,
           ("left", "ankle_pitch"): -30, ("right", "shoulder_roll"): -85}),
    (0.2, {("left", "shoulder_pitch"): 60, ("left", "hip_pitch"): 25, ("left", "knee"): 40,
           ("left", "ankle_pitch"): 0,
           ("right", "hip_pitch"): -100, ("right", "knee"): 120}),
    (0.2, {("left", "knee"): 20, ("left", "ankle_pitch"): 25}),
    (0.3, {}),
    (0.5, {("right", "shoulder_roll"): 80, ("right", "shoulder_pitch"): -90,
           ("left", "knee"): 0}),
    (0.4, {("left", "shoulder_pitch"): -100, ("left", "hip_pitch"): -90, ("left", "knee"): 60,
           ("right", "knee"): 0, ("right", "shoulder_pitch"): -180}),
    (1.6, {}),
]  # fmt: skip


def keyframes(robot: Robot) -> tuple[np.ndarray, list[np.ndarray]]:
    """The keyframes' times (s, from the start) and joint goals (rad, clipped to the limits),
    from the zero pose."""
    q = np.zeros(len(robot.joint_names))
    times, poses = [0.0], []
    for duration, changes in ROLL:
        q = q.copy()
        for (side, role), deg in changes.items():
            q[robot.joint_names.index(robot.roles.joint(side, role))] = math.radians(deg)
        times.append(times[-1] + duration)
        poses.append(np.clip(q, robot.q_min, robot.q_max))
    return np.array(times), poses


def roll(robot: Robot, variation=None, yaw: float = 0.0, stiffness: float = 8.0, rate=50.0):
    """Drop on the back, play :data:`ROLL`, settle 0.5 s: (the front's z per 0.2 s, the side)."""
    sim, bus, _imu = make_sim(robot, variation, rate)
    drop(sim, robot, "supine", yaw)
    times, poses = keyframes(robot)
    poses = [sim.q()[7:].copy(), *poses]
    front: list[float] = []

    def target(tick: int, t: float) -> np.ndarray | None:
        if t > times[-1]:
            return None
        if tick % round(0.2 * rate) == 0:
            front.append(float(robot.frame_placement(sim.q(), "torso").rotation[2, 0]))
        k = min(int(np.searchsorted(times, t, side="right")) - 1, len(poses) - 2)
        s = min(1.0, (t - times[k]) / (times[k + 1] - times[k]))
        source.stiffness = stiffness
        return poses[k] + s * s * (3 - 2 * s) * (poses[k + 1] - poses[k])

    source = CallableSource(target, poses[0], robot.joint_names)
    config = DeployConfig(rate=rate, read=bus.can_read, soft_speed=0.5)
    Deployment(bus, source, robot, config, out=lambda _line: None).run()
    sim.advance(0.5)
    R = robot.frame_placement(sim.q(), "torso").rotation
    front.append(float(R[2, 0]))
    return front, lying_side(R) or "side"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="bioloid")
    ap.add_argument("--models", type=int, default=5)
    ap.add_argument("--seed", type=int, default=33)
    ap.add_argument("--nominal", action="store_true", help="also the nominal model")
    ap.add_argument("--stiffness", type=float, default=8.0)
    args = ap.parse_args(argv)
    robot = load_robot(args.robot)
    variations = ([None] if args.nominal else []) + models(robot, args.models, args.seed)
    yaws = np.random.default_rng(args.seed).uniform(-math.pi, math.pi, len(variations))
    ends: dict[str, int] = {}
    for k, (v, yaw) in enumerate(zip(variations, yaws, strict=True)):
        front, side = roll(robot, v, float(yaw), args.stiffness)
        ends[side] = ends.get(side, 0) + 1
        name = "nominal" if v is None else k - int(args.nominal)
        print(f"model {name}: ends {side}; front z min {min(front):+.2f}, "
              f"over the roll {' '.join(f'{z:+.1f}' for z in front)}", flush=True)  # fmt: skip
    print(", ".join(f"{n} {side}" for side, n in ends.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
