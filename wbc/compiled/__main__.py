"""Compile (and cache on disk) the control ticks of the package's task types now:
``python -m wbc.compiled`` after installing, so that the first control loop starts at once.

Two processes work in parallel, one per solver (``--part weighted`` and ``--part
hierarchical``): each builds the ``walk`` stack and solves a tick with an active inequality row
on the compiled tick, then on the numpy path (whose kernels Python calls), so that numba
compiles and caches every kernel a run of the package's stacks calls (``~/.cache/wbc`` or
``$WBC_CACHE_DIR``, and numba's ``__pycache__``). The solvers start the same processes
themselves at their first compiled tick when the cache is empty, solve on the numpy path
meanwhile and switch when their tick is cached (:meth:`wbc.compiled.dispatch.Ticks.ready`).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

#: the worker processes, one per solver of the compiled tick (they compile in parallel)
PARTS = ("weighted", "hierarchical")


#: set in a worker's environment: its own ticks compile in process (no workers of its own)
WORKER_ENV = "WBC_COMPILE_WORKER"


def command(part: str) -> list[str]:
    """The command line of the worker that compiles ``part``."""
    return [sys.executable, "-m", "wbc.compiled", "--part", part]


def worker_env() -> dict[str, str]:
    """A worker's environment: this one, marked as a worker's."""
    return {**os.environ, WORKER_ENV: "1"}


def compile_part(part: str) -> None:
    """Solve one tick of the ``walk`` stack with solver ``part`` on the compiled tick, then
    on the numpy path: numba compiles what each calls and caches it
    on disk. The compiled tick comes first: a solver waiting for it loads it from the cache
    as soon as it is there (:meth:`wbc.compiled.dispatch.Ticks.ready`), while the worker goes
    on with the numpy path's kernels."""
    from ..model import Kinematics, load_robot
    from ..stacks import load_stack

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
        prog="python -m wbc.compiled", description="compile and cache the control ticks"
    )
    parser.add_argument("--part", choices=PARTS, help="compile one solver's kernels only")
    args = parser.parse_args(argv)
    if args.part:
        compile_part(args.part)
        return 0
    start = time.perf_counter()
    print("wbc: compiling the control ticks (numba, 2 processes)...", flush=True)
    workers = [subprocess.Popen(command(p), env=worker_env()) for p in PARTS]
    failed = [p for p, w in zip(PARTS, workers, strict=True) if w.wait() != 0]
    if failed:
        print(f"wbc: compiling the {', '.join(failed)} tick failed", file=sys.stderr)
        return 1
    print(f"wbc: control ticks compiled and cached ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
