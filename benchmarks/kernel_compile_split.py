"""Where tests/test_compiled_lsq.py::test_each_kernel_compiles_once spends its time: the same
work as its subprocess (wbc.warmup.compile_part for the weighted and the hierarchical solver,
from empty caches, NUMBA_OPT=0), timed per part (wall, and this process's CPU in brackets: the
figure to compare on a loaded machine), then the signatures per compiled module and the
costliest compilations (numba's ``numba:compile`` events: CPU s without the callees compiled
inside it, then with them, and the number of such compilations of that kernel).

    rm -rf /tmp/nb /tmp/wbcc && NUMBA_CACHE_DIR=/tmp/nb WBC_CACHE_DIR=/tmp/wbcc \
        WBC_COMPILE_WORKER=1 NUMBA_OPT=0 PYTHONPATH=$PWD python benchmarks/kernel_compile_split.py
"""

from __future__ import annotations

import importlib
import pkgutil
import time

t0, c0 = time.perf_counter(), time.process_time()
from numba.core import event  # noqa: E402
from numba.core.registry import CPUDispatcher  # noqa: E402

import wbc.compiled as compiled_pkg  # noqa: E402
from wbc.model import Kinematics, load_robot  # noqa: E402
from wbc.stacks import load_stack  # noqa: E402


class Compiles(event.Listener):
    """Each compilation's CPU time, its callees' compilations (nested events) taken out."""

    def __init__(self) -> None:
        self.stack: list[list] = []  # [name, start, callees' CPU]
        self.spent: dict[str, list[float]] = {}  # name -> [own, with callees, count]

    def on_start(self, e: event.Event) -> None:
        f = e.data["dispatcher"].py_func
        self.stack.append([f"{f.__module__}.{f.__qualname__}", time.process_time(), 0.0])

    def on_end(self, e: event.Event) -> None:
        name, start, inner = self.stack.pop()
        spent = time.process_time() - start
        if self.stack:
            self.stack[-1][2] += spent
        row = self.spent.setdefault(name, [0.0, 0.0, 0])
        row[0] += spent - inner
        row[1] += spent
        row[2] += 1


compiles = Compiles()
event.register("numba:compile", compiles)
print(f"imports {time.perf_counter() - t0:.1f} s ({time.process_time() - c0:.1f} s)", flush=True)
robot = load_robot()
q = robot.configuration("stand")
for part in ("weighted", "hierarchical"):
    for path in (None, False):  # the compiled tick, then the numpy path (as compile_part)
        t, c = time.perf_counter(), time.process_time()
        control = load_stack("walk", robot, solver=part)
        control.solver.compiled = path
        control.set_phase("single", "l_sole", "r_sole", Kinematics(robot, q))
        swing = control.stack.task("frame_pose_swing")
        swing.set_position_target(swing.target_position - [0.0, 0.0, 0.005])
        control.solver.step(q, 0.01)
        what = "compiled tick" if path is None else "numpy path"
        print(f"{part} {what} {time.perf_counter() - t:.1f} s ({time.process_time() - c:.1f} s)",
              flush=True)  # fmt: skip
t, c = time.perf_counter(), time.process_time()
load_stack("cjl_com", robot).solver.step(q, 0.01)
print(f"cjl_com {time.perf_counter() - t:.1f} s ({time.process_time() - c:.1f} s)")
for info in pkgutil.iter_modules(compiled_pkg.__path__):
    mod = importlib.import_module(f"wbc.compiled.{info.name}")
    n = sum(
        len(v.signatures)
        for v in vars(mod).values()
        if isinstance(v, CPUDispatcher) and v.py_func.__module__ == mod.__name__
    )
    if n:
        print(f"  {info.name}: {n} signatures")
rows = sorted(compiles.spent.items(), key=lambda kv: -kv[1][0])
own = sum(r[0] for _, r in rows)
print(f"{sum(r[2] for _, r in rows)} compilations of {len(rows)} kernels, {own:.1f} s CPU:")
for name, (alone, inclusive, n) in rows[:15]:
    print(f"  {name}: {alone:.1f} s ({inclusive:.1f} s with its callees; {n}x)")
print(f"total {time.perf_counter() - t0:.1f} s ({time.process_time() - c0:.1f} s)")
