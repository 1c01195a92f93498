"""Compile (and cache on disk) the control ticks of the package's task types now:
``python -m wbc.compiled`` after installing, so that the first control loop starts at once.

Builds the ``walk`` stack with both solvers and solves one tick of each; numba caches every
kernel it compiles (``~/.cache/wbc`` or ``$WBC_CACHE_DIR``, and numba's ``__pycache__``).
"""

from __future__ import annotations

import logging
import time


def main() -> int:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from ..model import Kinematics, load_robot
    from ..stacks import load_stack

    start = time.perf_counter()
    robot = load_robot()
    q = robot.configuration("stand")
    for solver in ("weighted", "hierarchical"):
        control = load_stack("walk", robot, solver=solver)
        control.set_phase("single", "l_sole", "r_sole", Kinematics(robot, q))
        swing = control.stack.task("frame_pose_swing")
        swing.set_position_target(swing.target_position - [0.0, 0.0, 0.005])  # a row active
        control.solver.step(q, 0.01)
    print(f"wbc: control ticks compiled and cached ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
