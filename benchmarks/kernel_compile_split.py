"""Where tests/test_compiled_lsq.py::test_each_kernel_compiles_once spends its time: the same
work as its subprocess (wbc.warmup.compile_part for the weighted and the hierarchical solver,
from empty caches, NUMBA_OPT=0), timed per part, then the signatures per compiled module.

    rm -rf /tmp/nb /tmp/wbcc && NUMBA_CACHE_DIR=/tmp/nb WBC_CACHE_DIR=/tmp/wbcc \
        WBC_COMPILE_WORKER=1 NUMBA_OPT=0 PYTHONPATH=$PWD python benchmarks/kernel_compile_split.py
"""

from __future__ import annotations

import importlib
import pkgutil
import time

t0 = time.perf_counter()
from numba.core.registry import CPUDispatcher  # noqa: E402

import wbc.compiled as compiled_pkg  # noqa: E402
from wbc.model import Kinematics, load_robot  # noqa: E402
from wbc.stacks import load_stack  # noqa: E402

print(f"imports {time.perf_counter() - t0:.1f} s", flush=True)
robot = load_robot()
q = robot.configuration("stand")
for part in ("weighted", "hierarchical"):
    for path in (None, False):  # the compiled tick, then the numpy path (as compile_part)
        t = time.perf_counter()
        control = load_stack("walk", robot, solver=part)
        control.solver.compiled = path
        control.set_phase("single", "l_sole", "r_sole", Kinematics(robot, q))
        swing = control.stack.task("frame_pose_swing")
        swing.set_position_target(swing.target_position - [0.0, 0.0, 0.005])
        control.solver.step(q, 0.01)
        what = "compiled tick" if path is None else "numpy path"
        print(f"{part} {what} {time.perf_counter() - t:.1f} s", flush=True)
t = time.perf_counter()
load_stack("cjl_com", robot).solver.step(q, 0.01)
print(f"cjl_com {time.perf_counter() - t:.1f} s")
for info in pkgutil.iter_modules(compiled_pkg.__path__):
    mod = importlib.import_module(f"wbc.compiled.{info.name}")
    n = sum(
        len(v.signatures)
        for v in vars(mod).values()
        if isinstance(v, CPUDispatcher) and v.py_func.__module__ == mod.__name__
    )
    if n:
        print(f"  {info.name}: {n} signatures")
print(f"total {time.perf_counter() - t0:.1f} s")
