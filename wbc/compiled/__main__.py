"""Compile (and cache on disk) the control ticks of the package's task types now:
``python -m wbc.compiled`` after installing, so that the first control loop starts at once.

Two worker processes work in parallel, one per solver (:data:`wbc.compiled.workers.PARTS`,
each ``python -m wbc.warmup --part ...``: started by module name, the kernels import nothing
above them). The solvers start the same processes themselves at their first compiled tick
when the cache is empty, solve on the numpy path meanwhile and switch when their tick is
cached (:meth:`wbc.compiled.dispatch.Ticks.ready`).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time

from .workers import PARTS, command, worker_env


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m wbc.compiled", description="compile and cache the control ticks"
    )
    parser.parse_args(argv)
    start = time.perf_counter()
    print(f"wbc: compiling the control ticks (numba, {len(PARTS)} processes)...", flush=True)
    workers = [subprocess.Popen(command(p), env=worker_env()) for p in PARTS]
    failed = [p for p, w in zip(PARTS, workers, strict=True) if w.wait() != 0]
    if failed:
        print(f"wbc: compiling the {', '.join(failed)} tick failed", file=sys.stderr)
        return 1
    print(f"wbc: control ticks compiled and cached ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
