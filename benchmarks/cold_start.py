"""Time a first solve on a fresh install: numba's and wbc's caches pointed at empty
directories, then the ``walk`` stack built and solved once, in a new interpreter.

Run: ``python benchmarks/cold_start.py`` (prints wall and CPU seconds; caches are left alone).
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time

CHILD = """
from wbc import load_robot
from wbc.stacks import load_stack
robot = load_robot()
load_stack("walk", robot).solver.prepare(robot.configuration("walk_ready"), 0.01)
"""


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "NUMBA_CACHE_DIR": f"{tmp}/numba", "WBC_CACHE_DIR": f"{tmp}/wbc"}
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", CHILD], env=env, check=True)
        wall = time.perf_counter() - start
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(f"cold first solve: {wall:.0f} s wall, {usage.ru_utime + usage.ru_stime:.0f} s CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
