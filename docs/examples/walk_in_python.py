"""Build a walking reference, run a stack along it, and read the recording."""

import numpy as np

import wbc.stacks
from wbc import load_robot
from wbc.walking import GaitTiming, StandingState, forward_walk
from wbc.walking.loop import StackController, run

robot = load_robot("bioloid")
start = StandingState.from_robot(robot)  # Walk Ready: CoM and soles
ref = forward_walk(start, n_steps=4, step_length=0.03, timing=GaitTiming(step_time=0.4))
control = wbc.stacks.load_stack("walk", robot)
rec = run(StackController(control), robot, ref)  # one QP per 10 ms tick

com_err_mm = np.linalg.norm(rec["com"] - rec["com_ref"], axis=1) * 1e3
print(f"{len(rec)} ticks, {rec.t[-1]:.2f} s")
print(f"CoM error max {com_err_mm.max():.3f} mm")
print(f"ZMP margin min {rec['zmp_margin'].min() * 1e3:.1f} mm (achieved motion, > 0 inside)")
rec.save("walk.npz")  # wbc view / wbc deploy --dry-run read this file
