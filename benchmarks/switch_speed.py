"""Largest joint speed / no-load speed per robot and walk on a stack, anywhere, within a
tick of each support switch and on the non-leg joints (arms, head: issue 15's walk10 test asks
< 0.5 of the Bioloid's arms), beside what the reference itself asks (benchmarks/balance.md,
'Joint speed at a support switch').

    python benchmarks/switch_speed.py                       # each robot's own stack
    python benchmarks/switch_speed.py --stack my_walk.toml  # another (by name or path)

Each robot runs the stack its commands run (:func:`wbc.stacks.robot_stack`: the robot folder's
``stack.toml``, else ``tasks/walk.toml``) unless ``--stack`` names one for all. ``land``: the
reference's fastest swing-sole descent (mm/s) in the last :data:`LANDING_WINDOW` before a
touch-down (``SwingParams.landing`` sets how soft it is; a robot folder's ``robot.toml`` may
state it, ``--robots path/to/folder`` runs a copy).
"""

from __future__ import annotations

import argparse

import numpy as np

from wbc.bench import metrics
from wbc.bench.trajectories import build
from wbc.model import load_robot
from wbc.stacks import load_stack, robot_stack
from wbc.walking.feasibility import kinematic_feasibility
from wbc.walking.loop import StackController, run
from wbc.walking.sizing import SPEED_FRACTION

WALKS = ("static_walk", "walk10", "walk10_wb", "turn", "lateral", "turn_wb", "lateral_wb",
         "fast_wb")  # fmt: skip
#: s before a touch-down over which ``land`` is taken
LANDING_WINDOW = 0.04


def landing_speed(ref) -> float:
    """The swing soles' fastest descent (m/s, positive) within :data:`LANDING_WINDOW` before
    each touch-down of ``ref`` (the last tick of each swing; finite differences)."""
    n = round(LANDING_WINDOW / ref.dt)
    worst = 0.0
    for side, sole in (("left", ref.l_sole), ("right", ref.r_sole)):
        down = -np.gradient(sole[:, 2], ref.dt)
        for i in np.flatnonzero(np.diff(ref.swing_mask(side).astype(int)) == -1):
            worst = max(worst, float(down[max(i - n, 0) : i + 1].max()))
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stack", help="one stack for every robot (default: each robot's own)")
    parser.add_argument("--robots", nargs="+", default=["bioloid", "kokone", "op3"])
    parser.add_argument("--walks", nargs="+", default=list(WALKS))
    args = parser.parse_args()
    for name in args.robots:
        robot = load_robot(name)
        stack, said = robot_stack(robot, args.stack)
        print(f"{name}: {said}", flush=True)
        legs = {robot.joint_index(j) for s in ("left", "right") for j in robot.roles.leg(s)}
        others = [j for j in range(robot.n_joints) if j not in legs]
        worst = {"max": 0.0, "switch": 0.0}
        for walk in args.walks:
            ref = build(walk, robot)
            asked = kinematic_feasibility(robot, ref).speed_fraction
            rec = run(StackController(load_stack(stack, robot)), robot, ref)
            speed = np.abs(np.diff(rec.q[:, 7:], axis=0)) / ref.dt / robot.v_max
            switches = np.flatnonzero(np.diff(rec.channels["support"]))
            near = np.concatenate([np.arange(s - 1, min(s + 4, len(speed))) for s in switches])
            m = metrics.compute(rec, robot)
            worst["max"] = max(worst["max"], float(speed.max()))
            worst["switch"] = max(worst["switch"], float(speed[near].max()))
            print(
                f"{name:8s} {walk:12s} ref {asked:4.2f}  max {speed.max():4.2f}  switch "
                f"{speed[near].max():4.2f}  others {speed[:, others].max():4.2f}  com "
                f"{m['com_err_max_mm']:.3f} mm  foot {m['foot_err_max_mm']:.3f} mm  land "
                f"{1000 * landing_speed(ref):.0f} mm/s",
                flush=True,
            )
        over = "" if worst["max"] <= SPEED_FRACTION else f"  ABOVE the sized share {SPEED_FRACTION}"
        print(f"{name}: largest share at a switch {worst['switch']:.2f}, anywhere "
              f"{worst['max']:.2f}{over}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
