"""Compile (and cache on disk) the control ticks of the package's stacks: the worker that
``python -m wbc.compiled`` and the solvers start, one per solver.

``python -m wbc.warmup --part weighted`` (and ``--part hierarchical``) builds the ``walk``
stack and solves a tick with an active inequality row on the compiled tick, then on the
numpy path (whose kernels Python calls), so that numba compiles and caches every kernel a
run of the package's stacks calls (``~/.cache/wbc`` or ``$WBC_CACHE_DIR``, and numba's
``__pycache__``). It loads a stack, so it lives above the stacks; the compiled kernels start
it by its module name (:data:`wbc.compiled.workers.WORKER_MODULE`), never importing it.
"""

from __future__ import annotations

import argparse

from .compiled.workers import PARTS, share_compilations
from .model import Kinematics, load_robot


def compile_part(part: str) -> None:
    """Solve one tick of the ``walk`` stack with solver ``part`` on the compiled tick, then
    on the numpy path: numba compiles what each calls and caches it
    on disk. The compiled tick comes first: a solver waiting for it loads it from the cache
    as soon as it is there (:meth:`wbc.compiled.dispatch.Ticks.ready`), while the worker goes
    on with the numpy path's kernels."""
    from .stacks import load_stack  # (here: its import compiles kernels, see main)

    robot = load_robot()
    q = robot.configuration("stand")
    # the compiled tick, then the numpy path's kernels: rows, bounds, the solver's least
    # squares (the level cascade; the weighted one), which the numpy path calls from Python
    paths: tuple[bool | None, ...] = (None, False)
    for compiled in paths:
        control = load_stack("walk", robot, solver=part)
        control.solver.compiled = compiled
        control.set_phase("single", "l_sole", "r_sole", Kinematics(robot, q))
        swing = control.stack.task("frame_pose_swing")
        swing.set_position_target(swing.target_position - [0.0, 0.0, 0.005])  # a row active
        control.solver.step(q, 0.01)
    if part == "hierarchical":  # (Chan–Dubey has no row kernel: the numpy path)
        load_stack("cjl_com", robot).solver.step(q, 0.01)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m wbc.warmup", description="compile and cache one solver's control ticks"
    )
    parser.add_argument("--part", choices=PARTS, required=True, help="the solver to compile")
    args = parser.parse_args(argv)
    share_compilations()  # (WBC_COMPILE_LOCK=1: the kernels it shares compiled once)
    compile_part(args.part)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
