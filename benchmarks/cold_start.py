"""Cold start on a fresh install: numba's and wbc's caches pointed at empty directories, then
(1) the first solve of the ``walk`` stack with each solver, in a new interpreter, and (2) the
README's quick-start job, ``wbc bench --json … --plots …``: the time to its first result line
and to its end; each run cold (empty caches), then warm (the caches it filled).

Run: ``python benchmarks/cold_start.py [--job solve|bench|both]`` (prints a markdown table;
the caches live in a temporary directory, the user's own are left alone). Figures in
cold_start.md.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

FIRST_SOLVE = """
import time
start = time.perf_counter()
from wbc import load_robot
from wbc.stacks import load_stack
robot = load_robot()
q = robot.configuration("walk_ready")
for solver in ("weighted", "hierarchical"):
    s = load_stack("walk", robot, solver=solver).solver
    s.step(q, 0.01)
    assert s.compiled_ticks + s.handed_back_ticks == 1 and s.fast is not None
    print(f"{solver}: first tick after {time.perf_counter() - start:.1f} s", flush=True)
"""


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(cmd: list[str], env: dict, first: str | None) -> tuple[float, float, float | None]:
    """(wall s, CPU s of the process and the workers it waited for, wall s until the first
    stdout line containing ``first``)."""
    cpu = children_cpu()
    start = time.perf_counter()
    seen = None
    with subprocess.Popen(
        cmd, env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    ) as p:
        for line in p.stdout:
            if seen is None and first is not None and first in line:
                seen = time.perf_counter() - start
            sys.stderr.write("    | " + line)
    if p.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode})")
    return time.perf_counter() - start, children_cpu() - cpu, seen


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--job", choices=("solve", "bench", "both"), default="both")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as out:
        rows = measure(args.job, Path(out))
    print("| job | cache | wall s | CPU s | first result s |")
    print("|---|---|---|---|---|")
    for label, state, wall, cpu, seen in rows:
        first = "–" if seen is None else f"{seen:.0f}"
        print(f"| {label} | {state} | {wall:.0f} | {cpu:.0f} | {first} |")
    return 0


def measure(job: str, out: Path) -> list[tuple]:
    """(label, cold/warm, wall s, CPU s, first result s) of each run."""
    bench = [
        sys.executable, "-m", "wbc.cli", "bench", "--json", str(out / "bench.json"),
        "--plots", str(out / "plots"),
    ]  # fmt: skip
    jobs = [  # (label, command, what its first useful line holds)
        ("first solve, walk stack, both solvers", [sys.executable, "-c", FIRST_SOLVE], "weighted:"),
        ("`wbc bench --json … --plots …`", bench, "thesis_step"),  # a result line, or a table
    ]
    rows = []
    for label, cmd, first in jobs[:1] if job == "solve" else jobs[1:] if job == "bench" else jobs:
        with tempfile.TemporaryDirectory() as tmp:  # each job starts from empty caches
            env = {
                **os.environ,
                "NUMBA_CACHE_DIR": f"{tmp}/numba",
                "WBC_CACHE_DIR": f"{tmp}/wbc",
                "PYTHONPATH": str(ROOT),
                "PYTHONUNBUFFERED": "1",
            }
            for state in ("cold", "warm"):
                print(f"{label}, {state}...", file=sys.stderr, flush=True)
                wall, cpu, seen = timed(cmd, env, first)
                rows.append((label, state, wall, cpu, seen))
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
